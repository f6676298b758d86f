"""The drift kind's bench: the table axis's instruments plus the platform's waveform
generator and one digitizing DMM per gyro, typed (issue 45: no untyped `extra` bag).

A module of its own so that the kind's module stays light to import (`bench validate`
and the CLI's start-up load no instrument driver).
"""

from __future__ import annotations

from bench.core.instruments import Bench
from drivers.awg import WaveformGenerator
from drivers.dmm import Digitizer


class DriftBench(Bench):
    """What `DriftSteps.open_bench` opens; `awg` is None until the generator is open."""

    def __init__(self) -> None:
        super().__init__()
        self.awg: WaveformGenerator | None = None
        self.dmms: dict[str, Digitizer] = {}
        #: FETC? answers taken per gyro this session (a cycle's event names its own)
        self.fetches: dict[str, int] = {}
        #: the amplitude the pair is loaded at on the generator, None before the first load
        self.loaded_v: float | None = None
