"""What the engine and the procedure kinds need of each instrument: small capability
protocols, as Bluesky's `protocols.py` states what a device must offer.

The drivers (drivers/axis.py, drivers/counter.py, drivers/fog.py) satisfy them
structurally; a kind written against these names works with any driver that offers the
same capabilities (another drive family, a counter of another maker), and the type
checker says so before a run does. Each protocol lists only what bench/ and procedures/
call: a driver is free to offer more.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np

from drivers.cia402 import DriveUnits
from drivers.counter import Acquisition, InputConfig, What
from drivers.fog import FogCheckpoint, FogSamples, FogStats
from drivers.json_types import Readback
from drivers.time_tie import TimeTie


class Drive(Protocol):
    """One table axis's servo drive: command a rate or a position, watch it, stop it."""

    name: str
    max_rate_dps: float
    @property
    def readback(self) -> Readback:
        """Settings read back at connect (journaled, shown on the certificate)."""
    units: DriveUnits   # the drive's velocity and acceleration units (factor group)

    def identity(self) -> str: ...

    def check(self) -> None:
        """Raise the drive's pending fault, if any."""

    def enable(self) -> None: ...

    def set_rate(self, rate_dps: float, accel_dps2: float | None = None) -> float: ...

    def wait_settled(self, tolerance_dps: float, hold_s: float, timeout_s: float,
                     on_hold: Callable[[float], None] | None = None) -> float: ...

    def move_to(self, position_deg: float, rate_dps: float, accel_dps2: float | None = None,
                tolerance_deg: float | None = None) -> float: ...

    @property
    def position_deg(self) -> float: ...

    def stop(self, wait: bool = True) -> None: ...

    def disable(self) -> None: ...

    def safe_stop(self, log: Callable[[str], None] | None = None) -> list[str]:
        """The one stop sequence (ramp, else quick stop; then disable); never raises."""


class Counter(Protocol):
    """A timestamping counter watching an axis's once-per-revolution zero mark."""

    @property
    def readback(self) -> Readback:
        """Settings read back at connect (journaled, shown on the certificate)."""
    time_tie: TimeTie
    last_acquisition: Acquisition | None

    def identify(self) -> str: ...

    def configure(self, channel: int = 1, level_v: float | None = None, slope: str = "POS",
                  coupling: str = "DC", impedance_ohm: float = 1.0e6) -> InputConfig: ...

    def verify_reference(self, reference: str | None,
                         timebase_limit_rel: float | None) -> str | None: ...

    def arm(self, n: int, expected_period_s: float, *, what: What = "edges",
            method: str | None = None) -> Acquisition: ...

    def fetch(self) -> np.ndarray: ...


class Fog(Protocol):
    """A gyro streaming rate samples on a fixed grid; the raw capture keeps every byte."""

    rate_hz: float
    units: str
    axis: str
    #: the capture's first sample index (placed by the clock at opening; None before)
    first_index: int | None

    @property
    def readback(self) -> Readback:
        """Settings read back at connect (journaled, shown on the certificate)."""

    @property
    def end_index(self) -> int: ...

    def identity(self) -> str: ...

    def wait_for_index(self, i: int, timeout_s: float) -> None: ...

    def checkpoint(self) -> FogCheckpoint: ...

    def samples(self, i_from: int, i_to: int) -> FogSamples: ...

    @property
    def stats(self) -> FogStats: ...

