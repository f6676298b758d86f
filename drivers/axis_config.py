"""The axis driver's configuration at connect (drivers/axis.py): the node checked to be
a CiA 402 drive with the stand's encoder resolution, its identity, its units read from
(or set in) the factor group, heartbeats both ways, its TPDOs checked to carry the
feedback on an event timer, NMT start, and the options that say how it stops.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from canopen.pdo.base import PdoMap

from drivers.axis_errors import AxisError
from drivers.axis_link import STATE_TIMEOUT_S
from drivers.axis_motion import AxisMotion
from drivers.cia402 import (
    COB_HEARTBEAT,
    NAMED_SI_UNITS,
    NMT_STATE_OPERATIONAL,
    Od,
    UnitFactors,
    si_unit_text,
)
from drivers.clock import can_channel_name, channel_opened
from drivers.drive_settings import DriveSettings
from drivers.heartbeat import HeartbeatProducer


class AxisConfiguration(AxisMotion):
    """The drive as found and set up when the axis opens."""

    settings: DriveSettings
    unit_factors_setting: str | Mapping[str, str]
    pdo_setting: str
    factors: UnitFactors | None
    readback: dict[str, Any]
    watchdog_ms: int | None
    controller_node_id: int
    drive_watchdog_ms: int | None
    abort_connection_option: int | None
    _identity: str | None
    _started: bool

    def _check_config(self, accel_dps2: float | None) -> None:
        where = f"axis {self.name} drive"
        if not 1 <= self.node_id <= 127:
            raise ValueError(f"{where}: node_id must be 1..127, got {self.node_id}")
        if not 1 <= self.controller_node_id <= 127 or self.controller_node_id == self.node_id:
            raise ValueError(f"{where}: controller_node_id {self.controller_node_id} must be "
                             f"1..127 and differ from the drive's node_id")
        for key, value, top in (("max_rate_dps", self.max_rate_dps, self.units.max_velocity_dps),
                                ("max_accel_dps2", self.max_accel_dps2,
                                 self.units.max_accel_dps2)):
            if not (math.isfinite(value) and 0 < value <= top):
                raise ValueError(f"{where}: {key} = {value} must be > 0 and at most {top:.6g} "
                                 f"(what the drive's units can carry)")
        if self.units.dps2_to_accel(self.max_accel_dps2) < 1:
            raise ValueError(f"{where}: max_accel_dps2 = {self.max_accel_dps2} is below one "
                             f"acceleration unit of the drive")
        if self.heartbeat_ms < 1 or self.heartbeat_ms > 0xFFFF:
            raise ValueError(f"{where}: heartbeat_ms must be 1..65535, got {self.heartbeat_ms}")
        if self.watchdog_ms is not None and not 2 * self.heartbeat_ms < self.watchdog_ms <= 0xFFFF:
            raise ValueError(f"{where}: watchdog_ms = {self.watchdog_ms} must exceed twice "
                             f"heartbeat_ms = {self.heartbeat_ms} (and be <= 65535)")
        if accel_dps2 is not None:
            self._check_accel(float(accel_dps2))

    def _configure(self) -> None:
        node = self._node()
        device_type = self._read(Od.DEVICE_TYPE)
        if device_type & 0xFFFF != 402:
            raise AxisError(f"axis {self.name}: node {self.node_id} is not a CiA 402 drive "
                            f"(0x1000 device type = 0x{device_type:08X})")
        self._identity = self._read_identity()
        self._check_resolution()
        self._read_unit_factors()
        # heartbeats both ways: ours (the drive's watchdog eats it), the drive's (we watch)
        # from a thread of ours, not the bus's periodic task (drivers/heartbeat.py says why)
        self._hb_task = HeartbeatProducer(
            self._network(), COB_HEARTBEAT + self.controller_node_id,
            bytes([NMT_STATE_OPERATIONAL]), self.heartbeat_ms / 1000.0,
            name=f"axis {self.name} heartbeat").start()
        self._write(Od.PRODUCER_HEARTBEAT, self.heartbeat_ms)
        self._configure_watchdog()
        self.readback["drive.heartbeat consumer 0x1016:1"] = (
            f"node {self.controller_node_id}, {self.drive_watchdog_ms} ms")
        max_v = self._read_optional(Od.MAX_PROFILE_VELOCITY)
        if max_v is not None:
            self.readback["drive.max profile velocity 0x607F"] = \
                f"{self.units.velocity_to_dps(int(max_v)):.6g} deg/s"
        self._started = True
        node.nmt.state = "OPERATIONAL"
        self._wait_real(lambda: self._drive_nmt == NMT_STATE_OPERATIONAL,
                        max(STATE_TIMEOUT_S, 5 * self.heartbeat_ms / 1000.0),
                        "the drive's heartbeat to show NMT operational", check=False,
                        real_time=True)
        node.tpdo.read()  # the drive's TPDO mapping and communication parameters, by SDO
        mapped: set[int] = set()
        periods = []
        tpdos = node.tpdo.map
        assert tpdos is not None  # canopen types PdoBase.map Optional; TPDO sets it
        for n, pdo in tpdos.items():
            if pdo.enabled and pdo.map:
                self._check_tpdo_timing(n, pdo)
                mapped |= {var.index for var in pdo.map}
                self.readback[f"drive.pdo (TPDO{n}) mapping"] = " + ".join(
                    f"0x{var.index:04X}" for var in pdo.map)
                pdo.add_callback(self._on_tpdo)
                if pdo.event_timer:
                    periods.append(pdo.event_timer / 1000.0)
        missing = {Od.VELOCITY_ACTUAL, Od.POSITION_ACTUAL, Od.STATUSWORD} - mapped
        if missing:
            names = ", ".join(f"0x{i:04X} {Od(i).name.lower()}" for i in sorted(missing))
            raise AxisError(f"axis {self.name}: the drive's TPDOs do not carry {names}")
        self._tpdo_period_s = max(periods, default=0.01)
        channel_opened(self.clock, can_channel_name(self.channel, self.node_id))
        want = self.settings.quick_stop_decel_dps2
        if want is not None:   # CiA 402 0x6085 (UNSIGNED32, acceleration units)
            self._write(Od.QUICK_STOP_DECELERATION, self.units.dps2_to_accel(want))
        quick = self._read_optional(Od.QUICK_STOP_DECELERATION)
        if want is not None and quick != self.units.dps2_to_accel(want):
            raise AxisError(f"axis {self.name}: drive.quick_stop_decel_dps2: wrote {want:g} "
                            f"deg/s^2, the drive's 0x6085 reads back {quick}")
        if quick:
            self._quick_stop_decel_dps2 = self.units.accel_to_dps2(quick)
        self.readback["drive.quick stop deceleration 0x6085"] = (
            f"{self._quick_stop_decel_dps2:.6g} deg/s^2" + ("" if quick else
                                                          " (not reported: our limit)"))
        self.abort_connection_option = self._read_optional(Od.ABORT_CONNECTION_OPTION)
        # 0x605A decides whether transition 16 exists (codes 5-8): the driver takes only
        # the arcs the configured code allows (cia402.path)
        self.quick_stop_option = self._read_optional(Od.QUICK_STOP_OPTION)
        self.readback["drive.quick stop option code 0x605A"] = str(self.quick_stop_option)
        self._journal("config", identity=self._identity,
                      counts_per_rev=self.units.counts_per_rev,
                      velocity_unit_counts_per_s=self.units.velocity_unit_counts_per_s,
                      accel_unit_counts_per_s2=self.units.accel_unit_counts_per_s2,
                      heartbeat_ms=self.heartbeat_ms, drive_watchdog_ms=self.drive_watchdog_ms,
                      abort_connection_option=self.abort_connection_option,
                      quick_stop_decel_dps2=self._quick_stop_decel_dps2,
                      max_rate_dps=self.max_rate_dps, max_accel_dps2=self.max_accel_dps2,
                      factors=self.factors.as_record() if self.factors else None,
                      readback=self.readback)

    def _read_unit_factors(self) -> None:
        """The factor group (0x608F, 0x6091, 0x6096, 0x6097, 0x60A9, 0x60AA): what one
        velocity and acceleration unit of this drive is, read (or set, then read) at
        connect, because common drives default to rpm or inc/s, not our 0.001 count/s.

        A drive without the SI unit objects keeps the stand's conversion (journaled as
        such). The stand's limits are checked again in the drive's real units.
        """
        want = self.unit_factors_setting
        if not isinstance(want, str):
            for key, index in (("velocity", Od.SI_UNIT_VELOCITY),
                               ("acceleration", Od.SI_UNIT_ACCELERATION)):
                if key in want:
                    self._write(index, NAMED_SI_UNITS[want[key]])

        def pair(index: Od) -> tuple[int, int]:
            a, b = self._read_optional(index, 1), self._read_optional(index, 2)
            return (1, 1) if a is None or b is None else (int(a), int(b))

        v_si = self._read_optional(Od.SI_UNIT_VELOCITY)
        a_si = self._read_optional(Od.SI_UNIT_ACCELERATION)
        if v_si is None or a_si is None:
            self.readback["drive.unit_factors"] = "no SI unit objects: the stand's units"
            return
        inc, revs = pair(Od.POSITION_ENCODER_RESOLUTION)
        gear = pair(Od.GEAR_RATIO)
        factors = UnitFactors(inc, revs, gear[0], gear[1], int(v_si), int(a_si),
                              pair(Od.VELOCITY_FACTOR), pair(Od.ACCELERATION_FACTOR))
        if not isinstance(want, str):
            for key, code in (("velocity", factors.velocity_si),
                              ("acceleration", factors.acceleration_si)):
                if key in want and code != NAMED_SI_UNITS[want[key]]:
                    raise AxisError(f"axis {self.name}: drive.unit_factors.{key}: wrote "
                                    f"{want[key]}, the drive reads back "
                                    f"{si_unit_text(code)}")
        try:
            units = factors.drive_units()
        except ValueError as e:
            raise AxisError(f"axis {self.name}: drive.unit_factors: {e}") from e
        if units.counts_per_rev != self.units.counts_per_rev:
            raise AxisError(f"axis {self.name}: drive.counts_per_rev = "
                            f"{self.units.counts_per_rev} but the drive's 0x608F/0x6091 give "
                            f"{units.counts_per_rev} increments per revolution")
        self.units = units
        self.factors = factors
        self.readback.update({f"drive.factor {k}": v for k, v in factors.as_record().items()})
        try:
            self._check_config(None)
        except ValueError as e:
            raise AxisError(f"{e} (in the drive's units as read back: "
                            f"{si_unit_text(factors.velocity_si)}, "
                            f"{si_unit_text(factors.acceleration_si)})") from e

    def _check_tpdo_timing(self, n: int, pdo: PdoMap) -> None:
        """CiA 301 TPDO communication (0x1800+n-1): sub 2 transmission type, sub 5 event
        timer (ms). Types 254/255 send on an event; with event timer 0 the event is only a
        change of the mapped data, so a table at rest would send nothing and the
        standstill wait would stall. Types 1..240 need a SYNC producer we do not run.
        With drive.pdo: set, the driver writes type 255 and a 10 ms timer (the PDO
        disabled while it does, CiA 301 7.5.2.35) and reads them back.
        """
        key = f"drive.pdo (TPDO{n})"
        ok = pdo.trans_type in (254, 255) and bool(pdo.event_timer)
        if not ok and self.pdo_setting == "set":
            pdo.trans_type, pdo.event_timer = 255, 10
            pdo.save()
            pdo.read()
            ok = pdo.trans_type in (254, 255) and bool(pdo.event_timer)
        self.readback[f"{key} transmission type"] = pdo.trans_type
        self.readback[f"{key} event timer ms"] = pdo.event_timer
        if not ok:
            raise AxisError(f"axis {self.name}: {key}: transmission type {pdo.trans_type}, "
                            f"event timer {pdo.event_timer} ms: the drive would not send "
                            "feedback at rest (or only on SYNC); set drive.pdo: set, or "
                            "configure the drive for event-driven TPDOs with a timer")

    def _read_identity(self) -> str:
        def text(index: Od) -> str:
            value = self._read_optional(index)
            return "?" if value is None else str(value).strip()
        ident = []
        for sub, label in ((1, "vendor"), (2, "product"), (3, "revision"), (4, "serial")):
            value = self._read_optional(Od.IDENTITY, sub)
            if value is not None:
                ident.append(f"{label} {value}" if sub == 4 else f"{label} 0x{value:08X}")
        return (f"{text(Od.DEVICE_NAME)}, hw {text(Od.HARDWARE_VERSION)}, "
                f"sw {text(Od.SOFTWARE_VERSION)}, " + ", ".join(ident))

    def _check_resolution(self) -> None:
        increments = self._read_optional(Od.POSITION_ENCODER_RESOLUTION, 1)
        revolutions = self._read_optional(Od.POSITION_ENCODER_RESOLUTION, 2)
        if increments is None or revolutions is None:
            return  # a drive without 0x608F: the stand file's counts_per_rev is all we have
        if revolutions and increments / revolutions != self.units.counts_per_rev:
            raise AxisError(f"axis {self.name}: stand file says counts_per_rev = "
                            f"{self.units.counts_per_rev} but the drive's 0x608F says "
                            f"{increments}/{revolutions} counts per revolution")

    def _configure_watchdog(self) -> None:
        """Make the drive watch our heartbeat (0x1016:1), keeping its own time if sane."""
        entry = self._read(Od.CONSUMER_HEARTBEAT, 1)
        producer, time_ms = (entry >> 16) & 0xFF, entry & 0xFFFF
        if self.watchdog_ms is not None:
            time_ms = self.watchdog_ms
        elif producer != self.controller_node_id or time_ms <= 2 * self.heartbeat_ms:
            time_ms = 5 * self.heartbeat_ms
        new = (self.controller_node_id << 16) | time_ms
        if new != entry:
            self._write(Od.CONSUMER_HEARTBEAT, new, 1)
        self.drive_watchdog_ms = time_ms


    def identity(self) -> str:
        """Device name, versions and identity object (0x1008/0x1009/0x100A/0x1018)."""
        if self._identity is None:
            self._require_open()
            self._identity = self._read_identity()
        return self._identity
