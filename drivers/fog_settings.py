"""A stand axis's FOG, declared once: the `fog:` block of the stand file.

A msgspec Struct like the drive's (drivers/drive_settings.py). The live driver, the
twin, the analysis reading the raw capture, the disk-space estimate and the station
view all read the FOG's settings from here.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Annotated, Any, Literal

import msgspec
from msgspec import Meta, Struct

from drivers.calibration import Calibration
from drivers.fog_format_names import FORMAT_NAMES as FOG_FORMATS

#: the KVH DSP-1760's measuring range, deg/s, where the stand states none
DEFAULT_RANGE_DPS = 490.0


class FogSettings(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """A stand's `fog:` block, parsed once."""

    port: Annotated[str, Meta(description="serial port, e.g. /dev/ttyUSB0")]
    baudrate: Annotated[int, Meta(ge=1200, le=16_000_000,
                                  description="serial line rate")] = 921600
    format: Annotated[str, Meta(description="frame format (drivers/fog_formats.py)",
                                extra={"choices": FOG_FORMATS})] = "kvh-a"
    axis: Annotated[Literal["x", "y", "z"], Meta(
        description="the FOG axis along the table axis")] = "z"
    rate_hz: Annotated[float, Meta(ge=1, le=100_000, extra={"unit": "Hz"},
                                   description="the FOG's output (frame) rate")]
    range_dps: Annotated[float, Meta(
        gt=0, le=100_000, extra={"unit": "deg/s"},
        description="the FOG's measuring range: a rate above it is refused")] \
        = DEFAULT_RANGE_DPS
    units: Annotated[Literal["deg/s", "rad/s", "deg", "rad"], Meta(
        description="what the rotational fields carry; KVH's power-on default is delta "
                    "radians, 'rad' (1775 IMU Technical Manual, Table 5-10)")]
    configure: Annotated[Literal["set", "verify", "declare"], Meta(
        description="set: configure the FOG at connect and read back; verify: read back "
                    "only; declare: trust fog.units")] = "declare"
    serial: Annotated[str, Meta(
        description="the FOG's serial number: compared with its answer to ?IS at connect "
                    "(configure set or verify; KVH 1775 ICD 8.20), else printed as the "
                    "stand file states it; the key of its check values (bench "
                    "control)")] | None = None
    model: Annotated[str, Meta(description="maker and model, for the "
                                           "certificate")] | None = None
    sign: Annotated[int, Meta(
        ge=-1, le=1,
        description="+1: the FOG's sensitive axis along the table's positive sense (the "
                    "only mounting the analysis supports; a FOG mounted inverted is "
                    "refused)")] = 1
    calibration: Annotated[Calibration, Meta(
        description="the FOG's calibration certificate, if any")] | None = None

    def __post_init__(self) -> None:
        """`fog.sign: -1` was once accepted and never read: the analysis took an inverted
        FOG as upright (issue 25). Until the sign is carried through the twin, the
        capture and the cross-calibration, an inverted mounting is refused, not silently
        mis-signed."""
        if self.format not in FOG_FORMATS:
            raise ValueError(f"format: {self.format!r}: one of {', '.join(FOG_FORMATS)}")
        if self.sign != 1:
            raise ValueError("sign: only +1 is supported: mount the FOG with its sensitive "
                             "axis along the table's positive sense (an inverted FOG would "
                             "give figures of the wrong sign)")

    @classmethod
    def of_axis(cls, stand: Mapping[str, Any], axis: str) -> FogSettings | None:
        """The FOG of `axis` in a stand mapping read back from a run directory, or None
        when the axis has none (or the file is damaged: the station view reads run
        directories it did not write)."""
        f = ((stand.get("axes") or {}).get(axis) or {}).get("fog")
        if not isinstance(f, dict) or not all(k in f for k in ("port", "rate_hz", "units")):
            return None
        try:
            return msgspec.convert(f, cls)
        except (TypeError, ValueError, msgspec.ValidationError):  # a wrong or unknown key
            return None
