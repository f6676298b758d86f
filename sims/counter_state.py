"""The counter twin's state: its settings as the instrument holds them (what its
constructor is given, the stand's wiring and truth, and what *RST restores), and the
measurement in progress.

The bottom layer of the counter twin (sims/counter_twin.py): the measurement engine and
the command tables above it read and set these.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from drivers.counter_profiles import CounterProfile
from sims.clock import SteppedClock, VirtualClock
from sims.counter_models import TwinProfile
from sims.scpi_server import ScpiServer
from sims.stand import AxisModel, SimulatedStand


@dataclass
class InputState:
    """One input channel's settings as the twin holds them (*RST values)."""

    coupling: str = "AC"
    impedance_ohm: float = 1.0e6
    level_auto: bool = True
    level_v: float = 0.0
    slope: str = "POS"


@dataclass(frozen=True)
class SyncLink:
    """The FOG's sync output wired to the counter's external trigger: a pulse at FOG time
    k * period_s (every n-th sample), reaching the counter `latency_s` later with a
    Gaussian `jitter_s` (std) of its own."""

    period_s: float
    latency_s: float = 0.0
    jitter_s: float = 0.0

    def next_pulse_s(self, t_s: float, rng: np.random.Generator) -> float:
        """When the first sync pulse after stand time t_s reaches the counter."""
        k = math.floor(t_s / self.period_s) + 1
        return k * self.period_s + self.latency_s + self.jitter_s * float(rng.standard_normal())


Kind = Literal["timestamps", "periods", "totals"]


@dataclass
class TwinAcquisition:
    """A measurement in progress (or done) on the twin."""

    kind: Kind
    n: int                      # readings
    channel: int
    t_arm_s: float              # stand time of INIT / READ?
    timeout_s: float | None     # the instrument's own per-reading timeout, virtual s
    blind: bool                 # no edges reach the counter (set-up or 'no-trigger')
    t_start_s: float = 0.0      # the start event: INIT, or the sync pulse (TRIG:SOUR EXT)
    values: np.ndarray | None = None
    edges_s: np.ndarray = field(default_factory=lambda: np.empty(0))
    fetched: int = 0            # results already sent by FETC:ARR?
    removed: int = 0            # reading-memory items removed by R? / DATA:REM?
    #: stamp 0: the start event, or (first_value "edge-to-edge") the first edge after it
    edge_to_edge: bool = False
    stamp0_s: float | None = None
    #: frequency readings (CONF:FREQ, MEAS:FREQ?): 1 / period
    invert: bool = False
    #: gated readings (CNT-91 ACQ:APER): each spans whole turns until the gate time has
    #: passed; back to back, the next starts where it ended (no dead time)
    walk: bool = False
    gate_s: float = 0.0
    back_to_back: bool = False
    #: TRIG:SOUR BUS (53230A): each of `blocks` triggers (*TRG) starts `n / blocks`
    #: readings; `triggers` holds their stand times, the first is the start event
    bus: bool = False
    blocks: int = 1
    triggers: list[float] = field(default_factory=list)
    #: every trigger received so far has been served: the next reading waits for *TRG
    waiting_trigger: bool = False

    @property
    def edges_needed(self) -> int:
        if self.kind == "timestamps":
            return self.n + (1 if self.edge_to_edge else 0)
        if self.kind == "totals":
            return 0
        return 2 * self.n

    @property
    def edges_per_reading(self) -> int:
        return 1 if self.kind == "timestamps" else 2


class CounterSettings(ScpiServer):
    """The counter's settings: its wiring (constructor) and its *RST values (`reset`)."""

    profile: CounterProfile
    #: what the twin of this model does beyond its profile (sims/counter_models.py)
    twin_profile: TwinProfile
    first_value: str
    stand: SimulatedStand
    axis: AxisModel
    clock: VirtualClock | SteppedClock
    signal_channel: int
    signal_v: tuple[float, float]
    inputs: dict[int, InputState]
    sync: SyncLink | None
    external_reference: bool
    reference: str
    timebase_offset_rel: float
    rng: np.random.Generator
    timeout_s: float | None
    acquisition: TwinAcquisition | None

    # -- state ----------------------------------------------------------------------------
    def reset(self) -> None:
        self.inputs = {ch: InputState() for ch in self.profile.channels}
        self.function: str | None = None
        self.function_channel = 1
        self.sample_count = 1
        self.trigger_source = "IMM"
        self.timestamp_info = False
        self.timestamp_rate_hz = 1.0e6
        self.gate = "DEF"
        self.acquisition = None
        # 53230A *RST values (Programmer's Reference: TRIG:COUN 1, TRIG:DEL 0,
        # TRIG:SLOP NEG, FORM ASC, FORM:BORD NORM, FREQ:MODE AUTO)
        self.trigger_count = 1
        self.trigger_delay_s = 0.0
        self.trigger_slope = "NEG"
        self.data_format = "ASC"
        self.ascii_digits = 15
        self.byte_order = "NORM"
        self.frequency_mode = "AUTO"
        self.invert = False
        self.tint_channels = (1, 2)      # CONF:TINT: start and stop channels
        self.totalize_gate_s = 0.1       # CONF:TOT:TIM gate (DEF 0.1 s)
        self.ts_layout = "stst"          # CNT-91: STSTamp or TSTAmp replies
        if self.twin_profile.rst_function is not None:  # 53230A: FREQ 1
            self.function = self.twin_profile.rst_function
            self.invert = self.twin_profile.rst_invert
        # CNT-91 (Programmer's Handbook): gate 10 ms, single measurements, arming IMM
        self.aperture_s = 0.01
        self.walk = self.back_to_back = self.continuous = False
        self.arm_source, self.arm_slope, self.arm_count = "IMM", "POS", 1
        self.interpolator_auto = True
