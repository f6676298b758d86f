"""The drift kind's journal records: what its steps did, for its analysis to read back.

Declared among the journal's events (bench/core/events.py, issue 61): the journal adds
`utc`, `t_s` and `session`; the analysis reads the same classes the steps wrote.
"""

from __future__ import annotations

from typing import ClassVar

from bench.core.events import Event
from drivers.dmm import DigitizerSetup


class DmmSetup(Event, tag="dmm_setup", frozen=True):
    """A gyro's DMM configured as a digitizer, its settings on the line as they were
    read back (drivers/dmm.py DigitizerSetup)."""

    SPREAD: ClassVar[str] = "setup"
    gyro: str
    setup: DigitizerSetup


class AwgLoaded(Event, tag="awg_loaded", frozen=True):
    """The alternating-sign pulse pair loaded on a gyro's generator channel
    (docs/method.md B1)."""

    gyro: str
    channel: int
    amplitude_v: float
    sample_rate_hz: float
    points: int
    lead_s: float


class Turned(Event, tag="turned", frozen=True):
    """The platform turned to a position (docs/method.md B2), as commanded and as read."""

    axis: str
    position_deg: float
    actual_deg: float


class Cycle(Event, tag="cycle", frozen=True):
    """One pulse cycle recorded: where the platform stood, when the generator triggered,
    and which fetch of each gyro's DMM holds its readings (docs/method.md B1-B3)."""

    unit: str
    position_deg: float
    actual_deg: float
    timing: bool
    amplitude_v: float
    t_trigger_s: float
    fetch: dict[str, int]
    samples: int
    interval_s: float
    first_sample_s: float
    tc_s: float
