"""One rate-table axis: a CiA 402 servo drive on CANopen, in profile velocity mode (and
profile position mode for a turn to an angle, `move_to`).

The same code drives a real drive and the drive twin (sims/drive_twin.py): it talks
CANopen through the `canopen` package over python-can, and takes the bus from the
stand file (`interface`, `channel`; `virtual` for the twin).

What it does, and why:
- On entering its context: SDO checks that the node is a CiA 402 drive with the
  configured encoder resolution, sets up heartbeats both ways (the drive produces
  every `heartbeat_ms`; the drive's heartbeat consumer 0x1016 watches ours, so a dead
  controller gets its table stopped by the drive itself), NMT start, profile velocity
  mode with zero target, then the 402 state machine to Operation enabled.
- Feedback (velocity actual 0x606C, position actual 0x6064, statusword 0x6041) comes
  by TPDO, stamped on arrival with the bench clock.
- Limits are checked before anything is sent: a rate or acceleration over the
  stand's limit raises `LimitError`; nothing is ever clipped.
- An EMCY from the drive, a boot-up, or a silent drive heartbeat becomes a pending
  `DriveFault`; `check()` (and every method that waits) raises it.
- Leaving the context, by return or by exception, ramps to zero and disables.

Time: heartbeats, SDO and TPDO periods are real time (the CAN side); ramps, holds and
settling are in the clock's seconds, and real-time timeouts are scaled by the slowest
the clock can run (`drivers.clock.min_speed`) with a margin.

Threads: `raw` and the feedback bookkeeping run in canopen's receive thread; the
engine's `raw` callable must be thread-safe (an exception in it is kept and raised by
the next `check()`).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:   # canopen is imported when an axis opens (`bench validate` reads constants)
    import canopen
    from canopen.emcy import EmcyError
    from canopen.pdo.base import PdoMap
    from canopen.sdo import SdoVariable

from drivers.axis_spec import (
    DEFAULT_HEARTBEAT_MS,
    DEFAULT_PDO,
    DEFAULT_POSITION_TOLERANCE_DEG,
    DEFAULT_UNIT_FACTORS,
)
from drivers.cia402 import (
    COB_HEARTBEAT,
    CONTROLLER_NODE_ID,
    DEFAULT_COUNTS_PER_REV,
    DEFAULT_EDS_PATH,
    HEARTBEAT_LOST,
    NAMED_SI_UNITS,
    NMT_STATE_OPERATIONAL,
    PROFILE_POSITION,
    PROFILE_VELOCITY,
    QUICK_STOP_STAYS,
    AbortReaction,
    Command,
    Cw,
    DriveUnits,
    Mode,
    Od,
    State,
    Sw,
    UnitFactors,
    decode_state,
    describe_error,
    path,
    si_unit_text,
    transition,
    unwrap_int32,
    wrap_int32,
)
from drivers.clock import (
    Clock,
    can_channel_name,
    channel_closed,
    channel_opened,
    consumed,
    real_budget_s,
    stepped,
)
from drivers.heartbeat import HeartbeatProducer
from drivers.settle import RippleJudgement, hold_spans_turns, judge_with_ripple
from drivers.waits import MIN_REAL_MARGIN_S, Deadline

log = logging.getLogger(__name__)

RawSink = Callable[[str, dict[str, Any]], None]

#: real seconds added to every wait scaled from the clock (CAN latency, thread wake-ups,
#: a loaded host): the bench's stated minimum (drivers/waits.py)
REAL_MARGIN_S = MIN_REAL_MARGIN_S
#: on a stepped clock (a co-simulation) waits for readings look this often, stand s
STEPPED_POLL_S = 0.05
#: real seconds to wait for one 402 state change or NMT start (the same minimum)
STATE_TIMEOUT_S = MIN_REAL_MARGIN_S
#: SDO response timeout, real seconds (canopen's 0.3 s is short on a loaded host)
SDO_TIMEOUT_S = 1.0
#: |velocity actual| below which a drive in a mode without a speed-zero bit is at rest
STANDSTILL_DPS = 1e-3


class AxisError(RuntimeError):
    """Something went wrong with an axis drive (names the axis and what).

    `axis_moving`: after this error the axis may still be turning (the stop registry's
    outcome carries it as a field: bench/core/stops.py)."""

    axis_moving: bool = False


class LimitError(AxisError, ValueError):
    """A command over the stand's limits: refused before anything was sent."""


class ObjectRefused(AxisError):
    """The drive answered an SDO with an abort (no such object, value out of range...)."""


#: the words that say, loudly, to the operator that an axis may still be turning
NOT_STOPPED = "COULD NOT BE TOLD TO STOP"


class DriveUnreachable(AxisError):
    """The drive cannot be told to stop (its heartbeat is silent): only its own heartbeat
    watchdog can stop the table now, once our heartbeat stops. Says so loudly."""

    axis_moving = True

    def __init__(self, axis: str, silence_s: float, watchdog_ms: int | None,
                 abort_option: int | None) -> None:
        try:
            reaction = AbortReaction(abort_option).name.lower().replace("_", " ") \
                if abort_option is not None else None
        except ValueError:
            reaction = f"option {abort_option}"
        what = (f"its heartbeat watchdog (0x1016, {watchdog_ms} ms) trips as our heartbeat "
                f"stops now" if watchdog_ms else "it watches no heartbeat of ours (0x1016 "
                "is 0): NOTHING STOPS IT but its own limits")
        then = (f" and reacts with {reaction} (0x6007)" if reaction and watchdog_ms else "")
        super().__init__(
            f"AXIS {axis.upper()} {NOT_STOPPED}: the drive has been silent for "
            f"{silence_s:.2f} s; {what}{then}. Check the table before going near it.")
        self.axis, self.silence_s, self.watchdog_ms = axis, silence_s, watchdog_ms


class AxisTimeout(AxisError, TimeoutError):
    """A wait (settling, standstill, state change) did not finish in time."""


class PositionError(AxisError):
    """A move ended, but not within the position tolerance of its target."""


class DriveFault(AxisError):
    """The drive reported a fault (EMCY), rebooted, or went silent.

    `code` is the EMCY error code (CiA 301/402), e.g. 0x8611 following error; 0x8130
    when the controller stopped hearing the drive's heartbeat.
    """

    def __init__(self, axis: str, node_id: int, code: int | None, description: str,
                 register: int = 0, t_s: float | None = None) -> None:
        self.axis = axis
        self.node_id = node_id
        self.code = code
        self.description = description
        self.register = register
        self.t_s = t_s
        where = f"axis {axis} (drive node {node_id})"
        what = f"0x{code:04X} {description}" if code is not None else description
        super().__init__(f"{where}: drive fault {what}")


@dataclass(frozen=True)
class Feedback:
    """One TPDO's worth of drive readings, stamped on arrival with the bench clock."""

    t_s: float
    velocity_dps: float
    position_deg: float
    statusword: int


@dataclass(frozen=True)
class _FaultInfo:
    code: int | None
    description: str
    register: int
    t_s: float


class Axis:
    """A table axis driven by a CiA 402 drive in profile velocity mode; a context manager."""

    def __init__(self, name: str, *, interface: str, channel: str, node_id: int,
                 max_rate_dps: float, max_accel_dps2: float, clock: Clock,
                 counts_per_rev: int = DEFAULT_COUNTS_PER_REV, velocity_unit_counts_per_s: float = 1.0e-3,
                 accel_unit_counts_per_s2: float = 1.0,
                 eds_path: str | Path = DEFAULT_EDS_PATH, heartbeat_ms: int = DEFAULT_HEARTBEAT_MS,
                 watchdog_ms: int | None = None, controller_node_id: int = CONTROLLER_NODE_ID,
                 accel_dps2: float | None = None, bitrate: int | None = None,
                 feedback_journal_s: float = 0.1,
                 position_tolerance_deg: float = DEFAULT_POSITION_TOLERANCE_DEG,
                 raw: RawSink | None = None, unit_factors: str | Mapping[str, str] = DEFAULT_UNIT_FACTORS,
                 pdo: str = DEFAULT_PDO, bus_options: Mapping[str, Any] | None = None) -> None:
        self.name = name
        self.interface = interface
        self.channel = channel
        #: more `can.Bus` arguments: a socketcand server's host and port
        self.bus_options = dict(bus_options or {})
        self.node_id = int(node_id)
        self.clock = clock
        self.eds_path = Path(eds_path)
        self.bitrate = bitrate
        self.raw = raw
        #: clock seconds between journaled feedback records (0: every TPDO; 100 Hz of
        #: TPDOs for a 10 h ladder would be millions of lines the analysis never reads)
        self.feedback_journal_s = float(feedback_journal_s)
        self._feedback_journaled_t: float | None = None
        self.units = DriveUnits(int(counts_per_rev), float(velocity_unit_counts_per_s),
                                float(accel_unit_counts_per_s2))
        #: "read" (the drive's factor group is the truth) or {velocity, acceleration}:
        #: SI unit names (cia402.NAMED_SI_UNITS) written at connect and read back
        self.unit_factors_setting = unit_factors
        if not isinstance(unit_factors, str):
            bad = [v for v in unit_factors.values() if v not in NAMED_SI_UNITS]
            if bad or set(unit_factors) - {"velocity", "acceleration"}:
                raise ValueError(f"axis {name} drive: unit_factors {dict(unit_factors)!r}: "
                                 f"keys velocity, acceleration; units one of "
                                 f"{', '.join(NAMED_SI_UNITS)}")
        elif unit_factors != "read":
            raise ValueError(f"axis {name} drive: unit_factors {unit_factors!r}: 'read' or "
                             "a mapping {velocity: ..., acceleration: ...}")
        if pdo not in ("set", "verify"):
            raise ValueError(f"axis {name} drive: pdo {pdo!r}: 'set' or 'verify'")
        self.pdo_setting = pdo
        #: the factor group and PDO timing as read back at connect (bench devices, journal)
        self.factors: UnitFactors | None = None
        self.readback: dict[str, Any] = {}
        self.max_rate_dps = float(max_rate_dps)
        self.max_accel_dps2 = float(max_accel_dps2)
        if not position_tolerance_deg > 0:
            raise ValueError(f"axis {name} drive: position_tolerance_deg must be > 0, "
                             f"got {position_tolerance_deg}")
        self.position_tolerance_deg = float(position_tolerance_deg)
        self.heartbeat_ms = int(heartbeat_ms)
        self.watchdog_ms = watchdog_ms
        self.controller_node_id = int(controller_node_id)
        self._check_config(accel_dps2)
        self.accel_dps2 = float(accel_dps2) if accel_dps2 is not None else self.max_accel_dps2
        self.mode: Mode = PROFILE_VELOCITY
        self.network: canopen.Network | None = None
        self.node: canopen.RemoteNode | None = None
        self._hb_task: HeartbeatProducer | None = None
        self._lock = threading.Condition()
        self._fault: _FaultInfo | None = None
        self._raw_error: BaseException | None = None
        self._identity: str | None = None
        self._drive_hb_last: float | None = None
        self._drive_nmt: int | None = None
        self._feedback: Feedback | None = None
        self._samples: deque[Feedback] = deque(maxlen=4096)
        #: the last settle's ripple judgement (None: judged reading by reading)
        self.last_settle: RippleJudgement | None = None
        self._seq = 0  # feedback frames received
        self._pos_raw: int | None = None
        self._pos_counts = 0
        self._statusword: int | None = None
        self._state: State | None = None
        self._tpdo_period_s = 0.01
        self._target_dps = 0.0
        self._accel_sent: int | None = None
        self._decel_dps2 = self.accel_dps2
        self._quick_stop_decel_dps2 = self.max_accel_dps2
        self.drive_watchdog_ms: int | None = None
        self.abort_connection_option: int | None = None  # 0x6007, read at connect
        self.quick_stop_option: int | None = None  # 0x605A, read at connect
        self._started = False

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

    # -- context --------------------------------------------------------------------
    def __enter__(self) -> Axis:
        self.open()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        try:
            self.close()
        except Exception as e:
            if exc is None:
                raise
            log.error("axis %s: stopping after %r failed: %s", self.name, exc, e)
            exc.add_note(f"axis {self.name}: stopping the axis afterwards failed too: {e}")

    def open(self) -> None:
        """Connect, configure, NMT start, enable in profile velocity mode at zero rate."""
        if self.network is not None:
            return
        import canopen
        network = canopen.Network()
        network.NOTIFIER_CYCLE = 0.1  # disconnect() waits up to one cycle
        node = canopen.RemoteNode(self.node_id, str(self.eds_path))
        node.sdo.RESPONSE_TIMEOUT = SDO_TIMEOUT_S
        network.add_node(node)
        node.nmt.add_heartbeat_callback(self._on_heartbeat)
        node.emcy.add_callback(self._on_emcy)
        kwargs: dict[str, Any] = {"interface": self.interface, "channel": self.channel,
                                  **self.bus_options}
        if self.bitrate:
            kwargs["bitrate"] = self.bitrate
        try:
            network.connect(**kwargs)
        except Exception as e:
            where = "".join(f" {k}={v}" for k, v in self.bus_options.items())
            raise AxisError(f"axis {self.name}: cannot open CAN bus {self.interface}:"
                            f"{self.channel}{where}: {e}") from e
        self.network, self.node = network, node
        self._started = False
        try:
            self._configure()
            self.enable()
        except BaseException:
            try:
                if self._started:  # NMT start was sent: the drive may be enabled
                    self.close()
                else:
                    self._leave_bus()
            except Exception as e:  # noqa: BLE001 - the first error is the one to see
                log.error("axis %s: cleanup after a failed open: %s", self.name, e)
            raise

    def close(self) -> None:
        """Ramp to zero, disable, stop our heartbeat, leave the bus. Safe to call twice."""
        if self.network is None:
            return
        errors: list[str] = []
        try:
            silence = self._drive_silence_s()
            if silence is not None:
                raise DriveUnreachable(self.name, silence, self.drive_watchdog_ms,
                                       self.abort_connection_option)
            errors = self.safe_stop()
        finally:
            self._leave_bus()
        if errors:
            raise AxisError(f"axis {self.name}: leaving: " + "; ".join(errors))

    def safe_stop(self, log: Callable[[str], None] | None = None) -> list[str]:
        """The one stop sequence (a run's end, an abort, a failed open): ramp to zero with
        the profile deceleration, else a quick stop; then disable. Returns what failed,
        raises nothing: the caller decides whose error the operator reads first."""
        say = log or (lambda text: None)
        errors: list[str] = []
        try:
            self.stop()
            say(f"  {self.name}: ramped to zero")
        except Exception as e:  # noqa: BLE001 - try the harder stop
            say(f"  {self.name}: ramp to zero failed ({e}); quick stop")
            errors.append(f"ramp to zero: {e}")
            try:
                self.quick_stop()
            except Exception as e2:  # noqa: BLE001
                errors.append(f"quick stop: {e2}")
        try:
            self.disable()
            say(f"  {self.name}: disabled")
        except Exception as e:  # noqa: BLE001
            errors.append(f"disable: {e}")
        return errors

    def _leave_bus(self) -> None:
        network, self.network = self.network, None
        channel_closed(self.clock, can_channel_name(self.channel, self.node_id))
        if self._hb_task is not None:
            try:
                self._hb_task.stop()
            except Exception:  # noqa: BLE001 - the bus shutdown stops it anyway
                pass
            self._hb_task = None
        if network is not None:
            network.disconnect()

    # -- configuration ----------------------------------------------------------------
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
        quick = self._read_optional(Od.QUICK_STOP_DECELERATION)
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

    # -- the 402 state machine -------------------------------------------------------------
    def enable(self) -> None:
        """Fault reset if needed, profile velocity mode, zero target, then Operation enabled."""
        state = self._read_state()
        if state is State.FAULT_REACTION_ACTIVE:  # let the drive finish its fault reaction
            self._wait_standstill(self._quick_stop_decel_dps2)
            state = self._wait_state(State.FAULT)
        if state is State.QUICK_STOP_ACTIVE and self.quick_stop_option not in QUICK_STOP_STAYS:
            # 0x605A 0-4: the drive leaves quick stop for Switch on disabled by itself
            self._wait_standstill(self._quick_stop_decel_dps2)
            state = self._wait_state(State.SWITCH_ON_DISABLED)
        if state is State.FAULT:
            code = self._read(Od.ERROR_CODE)
            self._journal("fault_reset", code=f"0x{code:04X}", description=describe_error(code))
            self._write(Od.CONTROLWORD, 0)
            self._write(Od.CONTROLWORD, Cw.FAULT_RESET)
            state = self._wait_state(State.SWITCH_ON_DISABLED)
        with self._lock:
            self._fault = None
        self._select_mode(PROFILE_VELOCITY)
        self._write(Od.TARGET_VELOCITY, 0)  # a drive enables onto the set-point it holds
        self._target_dps = 0.0
        self._send_accel(self.accel_dps2)
        self._go_to(State.OPERATION_ENABLED)
        self._wait_real(lambda: self._feedback is not None
                        and self._state is State.OPERATION_ENABLED,
                        STATE_TIMEOUT_S + 5 * self._tpdo_period_s,
                        "TPDOs showing operation enabled")

    def _select_mode(self, mode: Mode) -> None:
        """Write 0x6060 and check 0x6061 shows it (modes are rows of cia402.MODES)."""
        self._write(Od.MODES_OF_OPERATION, mode.code)
        shown = self._read(Od.MODES_OF_OPERATION_DISPLAY)
        if shown != mode.code:
            raise AxisError(f"axis {self.name}: drive shows mode {shown} after 0x6060 = "
                            f"{mode.code} ({mode.name})")
        self.mode = mode

    def _go_to(self, target: State) -> None:
        state = self._read_state()
        try:
            commands = path(state, target, self.quick_stop_option)
        except ValueError as e:
            raise AxisError(f"axis {self.name}: {e}") from e
        for cmd in commands:
            arc = transition(state, cmd, self.quick_stop_option)
            assert arc is not None
            self._write(Od.CONTROLWORD, cmd.word)
            state = self._wait_state(arc.target)

    def _read_state(self) -> State:
        sw = self._read(Od.STATUSWORD)
        return decode_state(sw)

    def _wait_state(self, target: State) -> State:
        deadline = Deadline(STATE_TIMEOUT_S)
        t_end = self.clock.now() + STATE_TIMEOUT_S
        while True:
            state = self._read_state()
            if state is target:
                return state
            if stepped(self.clock):  # co-simulation: the drive changes on stand time
                if self.clock.now() > t_end:
                    raise AxisTimeout(f"axis {self.name}: drive did not reach {target.label} "
                                      f"(it shows {state.label})")
                self.clock.sleep(max(self._tpdo_period_s, STEPPED_POLL_S))
                continue
            if deadline.expired():
                raise AxisTimeout(f"axis {self.name}: drive did not reach {target.label} "
                                  f"(it shows {state.label})")
            time.sleep(0.002)

    @property
    def state(self) -> State | None:
        """The 402 state of the latest statusword received."""
        with self._lock:
            return self._state

    # -- commands ---------------------------------------------------------------------
    def _check_accel(self, accel_dps2: float) -> None:
        if not math.isfinite(accel_dps2) or accel_dps2 <= 0:
            raise LimitError(f"axis {self.name}: acceleration {accel_dps2} deg/s^2 must be "
                             f"a finite number > 0 (nothing was sent)")
        if accel_dps2 > self.max_accel_dps2:
            raise LimitError(f"axis {self.name}: acceleration {accel_dps2:g} deg/s^2 is over "
                             f"the stand's max_accel_dps2 = {self.max_accel_dps2:g} deg/s^2; "
                             f"refused, nothing was sent")
        if self.units.dps2_to_accel(accel_dps2) < 1:
            raise LimitError(f"axis {self.name}: acceleration {accel_dps2:g} deg/s^2 is below "
                             f"one drive acceleration unit; refused")

    def _check_rate(self, rate_dps: float) -> None:
        if not math.isfinite(rate_dps):
            raise LimitError(f"axis {self.name}: rate {rate_dps} deg/s is not a finite number "
                             f"(nothing was sent)")
        if abs(rate_dps) > self.max_rate_dps:
            raise LimitError(f"axis {self.name}: rate {rate_dps:g} deg/s is over the stand's "
                             f"max_rate_dps = {self.max_rate_dps:g} deg/s; refused, nothing "
                             f"was sent")

    def set_rate(self, rate_dps: float, accel_dps2: float | None = None) -> float:
        """Command a rate (deg/s, signed); returns the rate actually sent (drive units)."""
        rate_dps = float(rate_dps)
        accel = self.accel_dps2 if accel_dps2 is None else float(accel_dps2)
        self._check_rate(rate_dps)
        self._check_accel(accel)
        self.check()
        if self.mode is not PROFILE_VELOCITY:
            self._select_mode(PROFILE_VELOCITY)
        state = self.state
        if state is not State.OPERATION_ENABLED:
            raise AxisError(f"axis {self.name}: cannot set a rate, the drive is in "
                            f"{state.label if state else 'an unknown state'} "
                            f"(enable() brings it to operation enabled)")
        self._send_accel(accel)
        units = self.units.dps_to_velocity(rate_dps, limit_dps=self.max_rate_dps)
        self._write(Od.TARGET_VELOCITY, units)
        sent = self.units.velocity_to_dps(units)
        with self._lock:
            self._target_dps = sent
        self._journal("command", rate_dps=rate_dps, sent_dps=sent, velocity_units=units,
                      accel_dps2=accel)
        return sent

    def _send_accel(self, accel_dps2: float) -> None:
        units = self.units.dps2_to_accel(accel_dps2, limit_dps2=self.max_accel_dps2)
        if units != self._accel_sent:
            self._write(Od.PROFILE_ACCELERATION, units)
            self._write(Od.PROFILE_DECELERATION, units)
            self._accel_sent = units
            self._decel_dps2 = self.units.accel_to_dps2(units)

    def stop(self, wait: bool = True) -> None:
        """Ramp to zero with the profile deceleration; wait for standstill if `wait`.

        In any other state the drive is already stopping on its own (quick stop, fault
        reaction) or its power stage is off: this only waits for standstill.
        """
        self._require_alive()
        state = self._read_state()
        if state is State.OPERATION_ENABLED:
            self._write(Od.TARGET_VELOCITY, 0)
            if self.mode is not PROFILE_VELOCITY:  # e.g. mid-move: PV at zero takes over
                self._select_mode(PROFILE_VELOCITY)
            with self._lock:
                self._target_dps = 0.0
            self._journal("command", rate_dps=0.0, sent_dps=0.0, velocity_units=0,
                          accel_dps2=self._decel_dps2)
        if wait:
            self._wait_standstill(self._decel_dps2)

    def quick_stop(self, wait: bool = True) -> None:
        """Quick stop (controlword): the drive ramps with 0x6085 as its 0x605A option says."""
        self._require_alive()
        state = self._read_state()
        if state is State.OPERATION_ENABLED:
            self._write(Od.CONTROLWORD, Command.QUICK_STOP.word)
            self._journal("quick_stop")
        if wait:
            self._wait_standstill(self._quick_stop_decel_dps2)

    def disable(self) -> None:
        """Stop if moving, then open the power stage (Switch on disabled). Faults stay latched."""
        self._require_alive()
        state = self._read_state()
        if state.power_stage_on:
            self.stop(wait=True)
            state = self._read_state()
        if state is State.FAULT_REACTION_ACTIVE:  # at rest now: the drive goes to Fault itself
            state = self._wait_state(State.FAULT)
        if state not in (State.SWITCH_ON_DISABLED, State.FAULT, State.NOT_READY_TO_SWITCH_ON):
            self._go_to(State.SWITCH_ON_DISABLED)

    def _wait_standstill(self, decel_dps2: float) -> None:
        """Wait for statusword bit 12 (speed = 0) in a TPDO received after now."""
        with self._lock:
            seq0 = self._seq
            v = abs(self._feedback.velocity_dps) if self._feedback else self.max_rate_dps
        ramp_s = v / max(decel_dps2, 1e-9)
        timeout = real_budget_s(self.clock, ramp_s) + REAL_MARGIN_S + 5 * self._tpdo_period_s
        bit = self.mode.speed_zero_bit
        if bit is None:  # this mode's statusword has no speed-zero bit: velocity actual
            self._wait_real(lambda: self._seq > seq0 and self._feedback is not None
                            and abs(self._feedback.velocity_dps) <= STANDSTILL_DPS,
                            timeout, "standstill (velocity actual)", check=False)
            return
        self._wait_real(lambda: self._seq > seq0 and self._statusword is not None
                        and bool(self._statusword & bit),
                        timeout, "standstill (statusword bit 12)", check=False)

    # -- profile position ------------------------------------------------------------------
    def move_to(self, position_deg: float, rate_dps: float, accel_dps2: float | None = None,
                tolerance_deg: float | None = None) -> float:
        """Turn to an absolute position (deg, the drive's position actual) in profile
        position mode (0x6060 = 1, target 0x607A, cruise rate 0x6081) and wait there.

        Refused unless at rest and enabled. Returns the position actual at arrival;
        raises `PositionError` if it is not within `tolerance_deg` (default: the stand's
        position tolerance) of the target, `DriveFault` on a fault during the move.
        Afterwards the drive stays in profile position mode, holding; `set_rate` and
        `stop` go back to profile velocity.
        """
        position_deg, rate_dps = float(position_deg), float(rate_dps)
        accel = self.accel_dps2 if accel_dps2 is None else float(accel_dps2)
        tol = self.position_tolerance_deg if tolerance_deg is None else float(tolerance_deg)
        if not math.isfinite(position_deg):
            raise LimitError(f"axis {self.name}: target position {position_deg} deg is not "
                             f"a finite number (nothing was sent)")
        if not rate_dps > 0:
            raise LimitError(f"axis {self.name}: a move needs a rate > 0, got {rate_dps:g} "
                             f"deg/s (nothing was sent)")
        self._check_rate(rate_dps)
        self._check_accel(accel)
        self.check()
        if self.state is not State.OPERATION_ENABLED:
            raise AxisError(f"axis {self.name}: cannot move, the drive is in "
                            f"{self.state.label if self.state else 'an unknown state'}")
        start = self.feedback
        if abs(start.velocity_dps) > STANDSTILL_DPS or self.target_dps != 0.0:
            raise AxisError(f"axis {self.name}: a move starts from rest; stop first "
                            f"(velocity actual {start.velocity_dps:.6g} deg/s)")
        counts = self.units.deg_to_counts(position_deg)
        self._select_mode(PROFILE_POSITION)
        self._send_accel(accel)
        self._write(Od.PROFILE_VELOCITY_PP,
                    self.units.dps_to_velocity(rate_dps, limit_dps=self.max_rate_dps))
        self._write(Od.TARGET_POSITION, wrap_int32(counts))
        self._journal("move", target_deg=position_deg, from_deg=start.position_deg,
                      rate_dps=rate_dps, accel_dps2=accel, tolerance_deg=tol)
        enable = Command.ENABLE_OPERATION.word
        self._write(Od.CONTROLWORD, enable | Cw.NEW_SET_POINT | Cw.CHANGE_SET_IMMEDIATELY)
        self._wait_real(lambda: self._statusword is not None
                        and bool(self._statusword & Sw.SET_POINT_ACKNOWLEDGE),
                        STATE_TIMEOUT_S + 5 * self._tpdo_period_s,
                        "the drive to acknowledge the new position (statusword bit 12)")
        self._write(Od.CONTROLWORD, enable)
        dist = abs(position_deg - start.position_deg)
        move_s = dist / rate_dps + rate_dps / self._decel_dps2 + rate_dps / accel
        with self._lock:
            seq0 = self._seq

        def arrived() -> bool:  # in fresh TPDOs: target reached, and at rest
            f, sw = self._feedback, self._statusword
            return (self._seq > seq0 + 1 and f is not None and sw is not None
                    and bool(sw & Sw.TARGET_REACHED) and abs(f.velocity_dps) <= STANDSTILL_DPS)

        self._wait_real(arrived, real_budget_s(self.clock, 1.5 * move_s) + REAL_MARGIN_S
                        + 5 * self._tpdo_period_s, f"the move to {position_deg:g} deg")
        final = self.position_deg
        self._journal("moved", target_deg=position_deg, position_deg=final,
                      error_deg=final - position_deg)
        if abs(final - position_deg) > tol:
            raise PositionError(f"axis {self.name}: the move to {position_deg:g} deg ended at "
                                f"{final:.6f} deg, {final - position_deg:+.6f} deg off, outside "
                                f"the position tolerance {tol:g} deg")
        return final

    # -- readings ---------------------------------------------------------------------
    @property
    def feedback(self) -> Feedback:
        with self._lock:
            if self._feedback is None:
                raise AxisError(f"axis {self.name}: no feedback from the drive yet")
            return self._feedback

    @property
    def rate_dps(self) -> float:
        """Velocity actual 0x606C of the latest TPDO, deg/s."""
        return self.feedback.velocity_dps

    @property
    def position_deg(self) -> float:
        """Position actual 0x6064 of the latest TPDO, deg, unwrapped across INTEGER32 wraps."""
        return self.feedback.position_deg

    @property
    def target_dps(self) -> float:
        """The rate last sent (after rounding to drive units)."""
        with self._lock:
            return self._target_dps

    def wait_settled(self, tolerance_dps: float, hold_s: float, timeout_s: float,
                     on_hold: Callable[[float], None] | None = None) -> float:
        """Wait until the rate has stayed within tolerance for `hold_s` (clock s).

        Where the hold spans two whole turns or more, the turn's steady periodic ripple
        is set aside and the rest held to the tolerance (drivers/settle.py says why);
        otherwise every velocity reading of the hold must be within it. Returns the mean
        velocity actual over the hold (over whole turns: the fitted mean). Raises
        `AxisTimeout` when it does not settle within `timeout_s` (clock s), `DriveFault`
        on a drive fault. `on_hold` hears how long the readings have stayed within
        tolerance so far (clock s), for an operator watching the settle.
        """
        if not tolerance_dps > 0 or hold_s < 0 or not timeout_s > 0:
            raise ValueError(f"axis {self.name}: wait_settled needs tolerance_dps > 0, "
                             f"hold_s >= 0 and timeout_s > 0")
        deadline = Deadline(real_budget_s(self.clock, timeout_s) + REAL_MARGIN_S)
        t_end = self.clock.now() + timeout_s
        timed_out = False  # co-simulation: on stand time
        with self._lock:
            seq = self._seq
        run: list[Feedback] = []          # sample by sample: the trailing run within
        window: deque[Feedback] = deque()  # ripple set aside: the last hold_s of readings
        judged: RippleJudgement | None = None
        last_v: float | None = None
        last_target: float | None = None
        while True:
            self.check()
            with self._lock:
                new = list(self._samples)[-(self._seq - seq):] if self._seq > seq else []
                seq = self._seq
                target = self._target_dps
                state = self._state
            if state is not State.OPERATION_ENABLED:
                raise AxisError(f"axis {self.name}: the drive left operation enabled while "
                                f"settling (it shows {state.label if state else '?'})")
            if target != last_target:      # a new command: what was held no longer counts
                run.clear()
                window.clear()
                last_target = target
            ripple_rule = hold_spans_turns(hold_s, target)
            held_s = 0.0
            for f in new:
                last_v = f.velocity_dps
                if abs(f.velocity_dps - target) <= tolerance_dps:
                    run.append(f)
                else:
                    run.clear()
            if ripple_rule and new:
                window.extend(new)
                while len(window) >= 2 and window[-1].t_s - window[1].t_s >= hold_s:
                    window.popleft()
                judged = None
                if len(window) >= 2 and window[-1].t_s - window[0].t_s >= hold_s:
                    judged = judge_with_ripple([f.t_s for f in window],
                                               [f.velocity_dps for f in window],
                                               [f.position_deg for f in window],
                                               target, tolerance_dps)
                if judged is not None and judged.settled:
                    self._journal("settled", target_dps=target, mean_dps=judged.mean_dps,
                                  samples=len(window), hold_s=window[-1].t_s - window[0].t_s,
                                  tolerance_dps=tolerance_dps, rule="ripple set aside",
                                  ripple_peak_dps=judged.ripple_peak_dps,
                                  ripple_orders=judged.orders, turns=judged.turns,
                                  worst_residual_dps=judged.worst_residual_dps)
                    self.last_settle = judged
                    return judged.mean_dps
                if judged is not None and judged.last_out is not None:
                    held_s = window[-1].t_s - list(window)[judged.last_out].t_s
                elif window:
                    held_s = window[-1].t_s - window[0].t_s
            elif len(run) >= 2:
                held_s = run[-1].t_s - run[0].t_s
            if on_hold is not None and new:
                on_hold(held_s)
            if not ripple_rule and len(run) >= 2 and run[-1].t_s - run[0].t_s >= hold_s:
                mean = math.fsum(f.velocity_dps for f in run) / len(run)
                self._journal("settled", target_dps=target, mean_dps=mean, samples=len(run),
                              hold_s=run[-1].t_s - run[0].t_s, tolerance_dps=tolerance_dps,
                              rule="every reading")
                self.last_settle = None
                return mean
            if timed_out or deadline.expired():
                ripple = (f"; with the turn's ripple ({judged.ripple_peak_dps:.3g} deg/s peak) "
                          f"set aside the rest still reached {judged.worst_residual_dps:.3g} "
                          "deg/s" if judged is not None else "")
                raise AxisTimeout(f"axis {self.name}: the rate did not settle within "
                                  f"{tolerance_dps:g} deg/s of {target:g} deg/s for {hold_s:g} s "
                                  f"in {timeout_s:g} s (last velocity actual: "
                                  f"{'none' if last_v is None else f'{last_v:.6g} deg/s'}"
                                  f"{ripple})")
            if stepped(self.clock):  # co-simulation: the next readings are stand time away
                if self.clock.now() > t_end:
                    timed_out = True
                    continue
                self.clock.sleep(max(self._tpdo_period_s, STEPPED_POLL_S))
                continue
            with self._lock:
                self._lock.wait(timeout=0.05)

    def identity(self) -> str:
        """Device name, versions and identity object (0x1008/0x1009/0x100A/0x1018)."""
        if self._identity is None:
            self._require_open()
            self._identity = self._read_identity()
        return self._identity

    def check(self) -> None:
        """Raise the pending fault, if any: EMCY, boot-up, silent drive, lost feedback."""
        network = self._require_open()
        network.check()
        now = time.monotonic()
        with self._lock:
            if self._raw_error is not None:
                err, self._raw_error = self._raw_error, None
                raise AxisError(f"axis {self.name}: the raw-data callback failed: {err}") \
                    from err
            last = self._drive_heard_s()
            if (self._fault is None and last is not None
                    and now - last > self._heartbeat_limit_s()):
                self._set_fault(HEARTBEAT_LOST.code,
                                f"no heartbeat from the drive for "
                                f"{now - last:.3f} s (it sends every "
                                f"{self.heartbeat_ms} ms)", 0)
            fault = self._fault
        if fault is not None:
            raise DriveFault(self.name, self.node_id, fault.code, fault.description,
                             fault.register, fault.t_s)

    # -- receive-thread callbacks ----------------------------------------------------------
    def _on_tpdo(self, pdo: PdoMap) -> None:
        t = self.clock.now()
        values = {var.index: var.raw for var in pdo.map}
        with self._lock:
            if Od.STATUSWORD in values:
                sw = int(values[Od.STATUSWORD])
                self._statusword = sw
                try:
                    state = decode_state(sw)
                except ValueError:
                    state = None
                if state is not self._state:
                    self._state = state
                    self._journal("state", state=state.label if state else f"0x{sw:04X}",
                                  statusword=sw)
            if Od.VELOCITY_ACTUAL in values or Od.POSITION_ACTUAL in values:
                prev = self._feedback
                v = (self.units.velocity_to_dps(int(values[Od.VELOCITY_ACTUAL]))
                     if Od.VELOCITY_ACTUAL in values else (prev.velocity_dps if prev else 0.0))
                if Od.POSITION_ACTUAL in values:
                    raw_pos = int(values[Od.POSITION_ACTUAL])
                    if self._pos_raw is None:
                        self._pos_counts = raw_pos
                    else:
                        self._pos_counts += unwrap_int32(self._pos_raw, raw_pos)
                    self._pos_raw = raw_pos
                f = Feedback(t, v, self.units.counts_to_deg(self._pos_counts),
                             self._statusword or 0)
                self._feedback = f
                self._samples.append(f)
                self._seq += 1
                last = self._feedback_journaled_t
                if last is None or t - last >= self.feedback_journal_s:
                    self._feedback_journaled_t = t
                    self._journal("feedback", t_s=t, velocity_dps=f.velocity_dps,
                                  position_deg=f.position_deg, statusword=f.statusword)
            self._lock.notify_all()
        consumed(self.clock, can_channel_name(self.channel, self.node_id), 1)

    def _on_heartbeat(self, nmt_state: int) -> None:
        with self._lock:
            self._drive_hb_last = time.monotonic()
            if nmt_state == 0 and self._drive_nmt is not None:
                self._set_fault(None, "the drive rebooted (boot-up message)", 0)
            self._drive_nmt = nmt_state
            self._lock.notify_all()

    def _on_emcy(self, entry: EmcyError) -> None:
        code, register = int(entry.code), int(entry.register)
        with self._lock:
            if code & 0xFF00 == 0:
                self._journal("emcy", code=f"0x{code:04X}", description="error reset",
                              register=register)
            else:
                self._journal("emcy", code=f"0x{code:04X}", description=describe_error(code),
                              register=register, data=bytes(entry.data).hex())
                self._set_fault(code, describe_error(code), register)
            self._lock.notify_all()

    def _set_fault(self, code: int | None, description: str, register: int) -> None:
        if self._fault is None:  # the first fault is the cause; later ones follow from it
            self._fault = _FaultInfo(code, description, register, self.clock.now())

    # -- plumbing ----------------------------------------------------------------------
    def _journal(self, kind: str, **record: Any) -> None:
        if self.raw is None:
            return
        record.setdefault("t_s", self.clock.now())
        try:
            self.raw(kind, record)
        except Exception as e:  # noqa: BLE001 - raised by the next check()
            self._raw_error = self._raw_error or e

    def _require_open(self) -> canopen.Network:
        if self.network is None:
            raise AxisError(f"axis {self.name}: not open (use it as a context manager)")
        return self.network

    def _drive_heard_s(self) -> float | None:
        """When the drive's heartbeat was last heard, or the end of a stall of this host
        (our own heartbeat thread woke late), if later: a drive's heartbeats sent while
        the host starved this process may not have been read yet; that is not silence."""
        if self._drive_hb_last is None:
            return None
        stall_end = self._hb_task.host_stall_end if self._hb_task is not None else 0.0
        return max(self._drive_hb_last, stall_end)

    def _heartbeat_limit_s(self) -> float:
        """Real silence after which the drive counts as gone: 4 heartbeats + 0.1 s, and
        never less than the bench's real-time minimum (a loaded controller PC can starve
        our receive thread that long; the drive's own watchdog guards the table)."""
        return max(4 * self.heartbeat_ms / 1000.0 + 0.1, MIN_REAL_MARGIN_S)

    def _drive_silence_s(self) -> float | None:
        """How long the drive has not sent a heartbeat, if longer than the limit."""
        with self._lock:
            last = self._drive_heard_s()
        if last is None:
            return None
        silence = time.monotonic() - last
        return silence if silence > self._heartbeat_limit_s() else None

    def _require_alive(self) -> None:
        """Fail fast on a silent drive: an SDO to it would only time out."""
        self._require_open()
        silence = self._drive_silence_s()
        if silence is not None:
            raise DriveFault(self.name, self.node_id, HEARTBEAT_LOST.code,
                             f"no heartbeat from the drive for {silence:.3f} s")

    def _network(self) -> canopen.Network:
        return self._require_open()

    def _node(self) -> canopen.RemoteNode:
        self._require_open()
        assert self.node is not None
        return self.node

    def _sdo_var(self, index: int, sub: int) -> SdoVariable:
        from canopen.sdo import SdoVariable
        obj = self._node().sdo[index]
        return obj if isinstance(obj, SdoVariable) else obj[sub]

    def _describe(self, index: int, sub: int) -> str:
        try:
            name = Od(index).name.lower().replace("_", " ")
        except ValueError:
            name = "object"
        return f"{name} 0x{index:04X}" + (f":{sub}" if sub else "")

    def _sdo(self, index: int, sub: int, value: int | None = None) -> Any:
        """One SDO read (value None) or write, with errors that name the axis and object."""
        what = self._describe(index, sub) + ("" if value is None else f" = {value}")
        verb = "reading" if value is None else "writing"
        from canopen.sdo import SdoAbortedError, SdoCommunicationError
        try:
            var = self._sdo_var(index, sub)
            if value is None:
                return var.raw
            var.raw = value
            return None
        except KeyError as e:
            raise ObjectRefused(f"axis {self.name}: {what} is not in the EDS "
                                f"{self.eds_path.name}") from e
        except SdoAbortedError as e:
            raise ObjectRefused(f"axis {self.name}: drive node {self.node_id} refused "
                                f"{verb} {what}: {e}") from e
        except SdoCommunicationError as e:
            raise AxisError(f"axis {self.name}: no answer from drive node {self.node_id} on "
                            f"{self.interface}:{self.channel} {verb} {what}: {e}") from e

    def _read(self, index: int, sub: int = 0) -> Any:
        return self._sdo(index, sub)

    def _read_optional(self, index: int, sub: int = 0) -> Any:
        """None when the drive does not have the object (optional in CiA 301/402)."""
        try:
            return self._sdo(index, sub)
        except ObjectRefused:
            return None

    def _write(self, index: int, value: int, sub: int = 0) -> None:
        self._sdo(index, sub, int(value))
        self._journal("write", object=self._describe(index, sub), value=int(value))

    def _wait_real(self, done: Callable[[], bool], timeout_real_s: float, what: str,
                   check: bool = True, real_time: bool = False) -> None:
        """Wait for `done()` (TPDO readings, unless `real_time`: heartbeats). On a
        stepped clock a wait for readings is on stand time, its limit taken as clock s."""
        if stepped(self.clock) and not real_time:
            t_end = self.clock.now() + timeout_real_s
            real_end = time.monotonic() + timeout_real_s + REAL_MARGIN_S
            while True:
                if check:
                    self.check()
                with self._lock:
                    if done():
                        return
                if self.clock.now() > t_end or time.monotonic() > real_end:
                    raise AxisTimeout(f"axis {self.name}: timed out after {timeout_real_s:.2f} "
                                      f"s (stand time) waiting for {what}")
                before = self.clock.now()
                self.clock.sleep(max(self._tpdo_period_s, STEPPED_POLL_S))
                if self.clock.now() <= before:  # paused: nothing moves on stand time
                    with self._lock:
                        self._lock.wait(timeout=0.02)
        deadline = Deadline(timeout_real_s)
        while True:
            if check:
                self.check()
            with self._lock:
                if done():
                    return
                if deadline.expired():
                    raise AxisTimeout(f"axis {self.name}: timed out after {timeout_real_s:.2f} "
                                      f"s (real) waiting for {what}")
                self._lock.wait(timeout=0.02)
