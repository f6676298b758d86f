"""The drive twin's own configuration, declared once: what a real drive holds in its
object dictionary at power-on and the bench does not set (its units, limits, windows,
serial number), with each value's unit and meaning.

A msgspec Struct, as the stand's drive settings are (drivers/drive_settings.py): the
twin (sims/drive_twin.py) takes it whole, and the stand's `sim.axes.<axis>.drive:` block
(bench/core/config.py) is read into it, its keys and meanings from this declaration.
"""

from __future__ import annotations

from typing import Annotated

from msgspec import Meta, Struct


def _dps(description: str, unit: str = "deg/s") -> Meta:
    return Meta(gt=0, description=description, extra={"unit": unit})


class DriveTruth(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """A drive twin's power-on configuration (its object dictionary's values)."""

    velocity_unit: Annotated[str | int, Meta(
        description="the velocity unit of the factor group 0x60A9, e.g. rpm, inc/s (or "
                    "its CiA 402 code)")] = "0.001 inc/s"
    acceleration_unit: Annotated[str | int, Meta(
        description="the acceleration unit 0x60AA, e.g. rpm/s, inc/s2 (or its CiA 402 "
                    "code)")] = "inc/s2"
    tpdo_event_timer_ms: Annotated[int, Meta(
        ge=0, extra={"unit": "ms"},
        description="the TPDOs' event timer 0x1800+n:5; 0: TPDOs on change only "
                    "(default: the EDS's)")] | None = None
    gear_ratio: Annotated[tuple[int, int], Meta(
        description="motor and shaft revolutions, 0x6091")] = (1, 1)
    servo_tolerance_dps: Annotated[float, _dps("velocity window 0x606D")] = 0.02
    watchdog_s: Annotated[float, _dps("its heartbeat consumer time 0x1016:1 at power-on",
                                      "s")] = 0.25
    max_rate_dps: Annotated[float, _dps("max profile velocity 0x607F")] = 720.0
    max_accel_dps2: Annotated[float, _dps("max acceleration 0x60C5", "deg/s^2")] = 1000.0
    max_decel_dps2: Annotated[float, _dps("max deceleration 0x60C6", "deg/s^2")] = 2000.0
    profile_accel_dps2: Annotated[float, _dps(
        "profile acceleration and deceleration 0x6083/0x6084", "deg/s^2")] = 200.0
    quick_stop_decel_dps2: Annotated[float, _dps("quick stop deceleration 0x6085",
                                                 "deg/s^2")] = 1000.0
    standstill_dps: Annotated[float, _dps("velocity threshold 0x606F")] = 0.001
    coast_decel_dps2: Annotated[float, _dps(
        "deceleration by friction alone, with the power stage off", "deg/s^2")] = 20.0
    position_window_deg: Annotated[float, _dps("position window 0x6067", "deg")] = 0.001
    pp_velocity_dps: Annotated[float, _dps("profile velocity 0x6081")] = 10.0
    #: the stand file states it in `sim.axes.<axis>.serials.drive`, not in this block
    serial_number: Annotated[int, Meta(
        ge=0, le=2**32 - 1, description="identity object 0x1018:4",
        extra={"file": False})] = 0
