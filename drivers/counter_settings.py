"""A stand axis's counter, declared once: the `counter:` block of the stand file.

A msgspec Struct like the drive's (drivers/drive_settings.py): each key's type, default,
bounds, unit (`Meta.extra["unit"]`) and meaning (`Meta.description`);
bench/core/schema.py reads it for `bench validate`, `bench schema` and
docs/configuration.md, and the loader builds it with msgspec.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from msgspec import Meta, Struct

from drivers.calibration import Calibration
from drivers.counter_profiles import DEFAULT_TIMEOUT_MARGIN_S
from drivers.counter_profiles import PROFILES as COUNTER_PROFILES
from drivers.time_tie import TimeTie

#: the counter's input range (a 10x probe on +/-5 V)
LEVEL_MAX_V = 50.0


class CounterSettings(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """A stand axis's `counter:` block: the instrument timing the zero-mark pulse."""

    resource: Annotated[str, Meta(description="VISA resource string")]
    model: Annotated[str, Meta(
        description="the counter's model: its driver profile (SCPI words, capabilities, "
                    "metrology; drivers/counter_profiles.py)",
        extra={"choices": tuple(sorted(COUNTER_PROFILES))})]
    serial: Annotated[str, Meta(
        description="the instrument's serial number: the key of its check values (bench "
                    "control)")] | None = None
    channel: Annotated[int, Meta(
        ge=1, le=4, description="input channel of the zero-mark pulse")] | None = None
    level_v: Annotated[float, Meta(
        ge=-LEVEL_MAX_V, le=LEVEL_MAX_V, extra={"unit": "V"},
        description="absolute trigger level; required on a real stand (a twin defaults "
                    "it)")] | None = None
    slope: Annotated[Literal["POS", "NEG"], Meta(
        description="the pulse edge timed")] | None = None
    coupling: Annotated[Literal["DC", "AC"], Meta(description="input coupling")] | None = None
    impedance_ohm: Annotated[float, Meta(
        gt=0, extra={"unit": "ohm"}, description="input impedance (50 or 1e6)")] | None = None
    trigger_jitter_s: Annotated[float, Meta(
        ge=0, extra={"unit": "s"}, description="slot sensor edge jitter, std")] | None = None
    timebase_limit_rel: Annotated[float, Meta(
        ge=0, description="timebase error limit (external reference)")] | None = None
    reference: Annotated[Literal["external", "internal"], Meta(
        description="timebase: set at connect and read back (53230A SENS:ROSC:SOUR); a "
                    "timebase_limit_rel below the model's needs 'external'")] | None = None
    timeout_margin_s: Annotated[float, Meta(
        gt=0, le=3600, extra={"unit": "s"},
        description="extra time allowed beyond a half's expected turns before the counter "
                    "counts as silent")] = DEFAULT_TIMEOUT_MARGIN_S
    calibration: Annotated[Calibration, Meta(
        description="the counter's calibration certificate")] | None = None
    #: None: the stand states none (twins: host clock)
    time_tie: Annotated[TimeTie, Meta(
        description="how the counter's start is tied to the FOG's time axis (docs/"
                    "configuration.md); a stand without a sim: block must state "
                    "it")] | None = None

    def __post_init__(self) -> None:
        if self.model not in COUNTER_PROFILES:
            raise ValueError(f"model: {self.model!r}: one of "
                             f"{', '.join(sorted(COUNTER_PROFILES))}")

    def input_settings(self) -> dict[str, Any]:
        """The input's settings the stand states (the driver's `configure` keywords)."""
        return {k: v for k in ("channel", "level_v", "slope", "coupling", "impedance_ohm")
                if (v := getattr(self, k)) is not None}
