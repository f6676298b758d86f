"""A CiA 402 servo drive on a CAN bus, turning one axis of the simulated stand.

The twin is a canopen LocalNode serving this project's EDS. Its state machine is the
table in drivers/cia402.py; its profile generator is the stand model's own ramp
(`AxisModel.command_rate`), so the FOG and counter twins see exactly the motion the
drive commands. Velocity and position actual values are the model's, sampled on the
stand's virtual clock.

Two time bases meet here, as on a real bench: the CAN side (heartbeats, TPDO event
timers, the heartbeat-consumer watchdog) runs in real time, while everything the
table does (ramps, stops, the velocity window and threshold timers) runs on the
stand's virtual clock.

canopen does not copy a LocalNode's data store into its TPDOs, so a tick thread does
it: every TPDO event timer (10 ms in the EDS) it advances the model, refreshes the
statusword bits that depend on motion, finishes ramps that end in a state change,
checks the watchdog, and transmits the TPDOs.

What a CiA 402/301 drive does and canopen's LocalNode does not, the twin adds (checked
with canopen's own BaseNode402, tests/test_drive_p402_client.py):
- NMT (CiA 301 7.3.2): Stopped, Reset Node and Reset Communication while the power stage
  is on take the abort-connection reaction 0x6007 (CiA 402); a reset restores its area
  of the OD and ends in a boot-up message and pre-operational; no SDO in Stopped; PDOs
  only in Operational.
- PDOs (CiA 301 7.5.2.35-38): COB-ID bit 31, transmission type (254/255 on event, 1-240
  every n-th SYNC), mapping (changed only while the PDO is not valid, sub-index 0 to 0
  before the entries; mappable objects at their own length, 64 bits at most) in effect as
  written; RPDOs write their objects as an SDO would, a synchronous one (0-240) at the
  next SYNC (CiA 301 7.2.2.3).
- CiA 402: transition 16 only for quick-stop codes 5-8; the halt bit with 0x605D;
  every quick-stop, shutdown, disable-operation and fault-reaction code; reserved option
  codes refused (abort 0x06090030); the factor group (0x608F, 0x6091, 0x6096, 0x6097,
  0x60A9, 0x60AA) applied when written, whole or not at all.

On the co-simulation clock (sims/clock.py SteppedClock) the ticks are the clock's events
instead, on a grid of stand time: every event timer while anything moves or changes
(a ramp, a state change, `ACTIVE_S` after any write from the controller, until target
reached; but no faster than `FINE_TICK_S`), every `STEADY_TICK_S` once the table turns
steadily (the TPDOs then carry
what the last one did, to within the noise, and 100 a second over a 29-hour ladder would
cost more than the measurement). The controller's consumption of the TPDOs is counted on
the channel `can_channel_name(channel, node)`, so each reading is stamped at the stand
time of its tick. The thread then only keeps the heartbeat watchdog, in real time.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import math
import struct
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import canopen
from canopen.nmt import NmtSlave
from canopen.objectdictionary import ODArray, ODVariable
from canopen.pdo.base import PdoBase, PdoMap, PdoMaps
from canopen.sdo import SdoAbortedError

from drivers.cia402 import (
    COB_HEARTBEAT,
    COB_SYNC,
    CONTROLLER_NODE_ID,
    DEFAULT_COUNTS_PER_REV,
    DEFAULT_EDS_PATH,
    FAULT_REACTION_OPTIONS,
    HALT_OPTIONS,
    HEARTBEAT_LOST,
    INT32_MAX,
    MODES,
    NAMED_SI_UNITS,
    OPTION_CODES,
    PROFILE_POSITION,
    PROFILE_VELOCITY,
    QUICK_STOP_OPTIONS,
    SLOW_DOWN_OPTIONS,
    UINT32_MAX,
    AbortReaction,
    Cw,
    DriveErrorCode,
    DriveUnits,
    Od,
    Ramp,
    State,
    Sw,
    UnitFactors,
    decode_command,
    describe_error,
    transition,
    wrap_int32,
)
from drivers.clock import can_channel_name
from sims.clock import SteppedClock
from sims.stand import AxisModel, SimulatedStand

log = logging.getLogger(__name__)

# SDO abort codes (CiA 301) the twin answers with
ABORT_VALUE_RANGE = 0x06090030
ABORT_VALUE_TOO_HIGH = 0x06090031
ABORT_VALUE_TOO_LOW = 0x06090032
ABORT_DEVICE_STATE = 0x08000022

ABORT_NOT_MAPPABLE = 0x06040041
ABORT_PDO_LENGTH = 0x06040042

#: CiA 301 NMT command specifiers and states (as canopen numbers them)
NMT_START, NMT_STOP, NMT_PRE_OPERATIONAL, NMT_RESET_NODE, NMT_RESET_COMM = 1, 2, 128, 129, 130
NMT_STOPPED, NMT_OPERATIONAL, NMT_PRE_OP, NMT_INITIALISING = 4, 5, 127, 0
#: real seconds from an NMT reset to the boot-up message (the drive re-initialising)
RESET_BOOT_S = 0.1
#: CiA 301 PDO communication parameter: COB-ID bit 31 "PDO not valid"
PDO_NOT_VALID = 1 << 31

UINT16_MAX = 0xFFFF
#: profile position: how many times the twin's position loop re-aims after a move
PP_MAX_CORRECTIONS = 5
#: a tick this many periods late means the twin itself was not run (a loaded host)
STARVED_TICKS = 5
#: co-simulation: stand seconds of ticks at the event timer after any controller write
ACTIVE_S = 3.0
#: co-simulation: stand seconds between ticks while the table turns steadily
STEADY_TICK_S = 30.0
#: co-simulation: the shortest stand time between ticks (the event timer's 10 ms would
#: make five steps of the clock for each one that matters to a settle or a ramp)
FINE_TICK_S = 0.05

#: objects whose value the twin computes when read (SDO or TPDO)
_LIVE = frozenset({Od.STATUSWORD, Od.MODES_OF_OPERATION_DISPLAY, Od.POSITION_ACTUAL,
                   Od.VELOCITY_ACTUAL, Od.ERROR_CODE, Od.ERROR_REGISTER})


@dataclass(frozen=True)
class WatchdogTrip:
    """When the heartbeat-consumer watchdog fired (real monotonic and stand times)."""

    last_heartbeat_real_s: float
    tripped_real_s: float
    tripped_t_s: float
    consumer_time_s: float
    reaction: AbortReaction

    @property
    def silence_s(self) -> float:
        """Real time from the controller's last heartbeat to the trip."""
        return self.tripped_real_s - self.last_heartbeat_real_s


class _DriveNmt(NmtSlave):
    """canopen's NMT slave takes every command as a bare state change: a reset never
    boots up again. The twin acts on each command as CiA 301 (7.3.2) and CiA 402 (0x6007)
    say; see DriveTwin._on_nmt."""

    def __init__(self, node_id: int, local_node: canopen.LocalNode, twin: DriveTwin) -> None:
        super().__init__(node_id, local_node)
        self._twin = twin

    def on_command(self, can_id: int, data: bytes, timestamp: float) -> None:
        cmd, node_id = struct.unpack_from("BB", data)
        if node_id in (self.id, 0):
            self._twin._on_nmt(cmd)


class DriveTwin:
    """The drive of `stand.axes[axis]` as CANopen node `node_id` on `interface:channel`."""

    def __init__(self, stand: SimulatedStand, axis: str, *, interface: str = "virtual",
                 channel: str, node_id: int, eds_path: str | Path = DEFAULT_EDS_PATH,
                 servo_tolerance_dps: float = 0.02, watchdog_s: float = 0.25,
                 controller_node_id: int = CONTROLLER_NODE_ID, counts_per_rev: int = DEFAULT_COUNTS_PER_REV,
                 velocity_unit: str | int = "0.001 inc/s",
                 acceleration_unit: str | int = "inc/s2",
                 gear_ratio: tuple[int, int] = (1, 1), tpdo_event_timer_ms: int | None = None,
                 max_rate_dps: float = 720.0,
                 max_accel_dps2: float = 1000.0, max_decel_dps2: float = 2000.0,
                 profile_accel_dps2: float = 200.0, quick_stop_decel_dps2: float = 1000.0,
                 standstill_dps: float = 0.001, coast_decel_dps2: float = 20.0,
                 position_window_deg: float = 0.001, pp_velocity_dps: float = 10.0,
                 serial_number: int = 0,
                 bus_options: Mapping[str, object] | None = None) -> None:
        if not 1 <= node_id <= 127:
            raise ValueError(f"drive twin node_id must be 1..127, got {node_id}")
        self.stand = stand
        self.axis = axis
        self.model: AxisModel = stand.axis(axis)
        self.clock = stand.clock
        self.interface = interface
        self.channel = channel
        #: more python-can bus arguments (a real bus interface's own)
        self.bus_options = dict(bus_options or {})
        self.node_id = node_id
        self._stepped = bool(getattr(self.clock, "stepped", False))
        self._leave: Callable[[], None] | None = None
        self._busy_until_s = 0.0
        self._can_name = can_channel_name(channel, node_id)
        self.eds_path = Path(eds_path)
        # the factor group (CiA 402 0x608F, 0x6091, 0x60A9, 0x60AA): the twin's units
        # follow from its own factor objects, as a real drive's do, and change when the
        # controller writes 0x60A9/0x60AA (outside Operation enabled)
        motor_revs = 1
        self.factors = UnitFactors(counts_per_rev * gear_ratio[1] // gear_ratio[0]
                                   if counts_per_rev * gear_ratio[1] % gear_ratio[0] == 0
                                   else counts_per_rev, motor_revs, gear_ratio[0],
                                   gear_ratio[1], _si(velocity_unit), _si(acceleration_unit))
        self.units: DriveUnits = self.factors.drive_units()
        self._factors0 = self.factors
        self._sync_count = 0
        self.coast_decel_dps2 = float(coast_decel_dps2)
        self._tpdo_event_timer_ms = tpdo_event_timer_ms
        #: unit-dependent objects as deg-based values, refitted when the units change
        self._deg_values = {
            "velocity": {(Od.VELOCITY_WINDOW, 0): ("servo_tolerance_dps", servo_tolerance_dps,
                                                   UINT16_MAX),
                         (Od.VELOCITY_THRESHOLD, 0): ("standstill_dps", standstill_dps,
                                                      UINT16_MAX),
                         (Od.MAX_PROFILE_VELOCITY, 0): ("max_rate_dps", max_rate_dps,
                                                        UINT32_MAX),
                         (Od.PROFILE_VELOCITY_PP, 0): ("pp_velocity_dps", pp_velocity_dps,
                                                       UINT32_MAX)},
            "accel": {(Od.MAX_ACCELERATION, 0): ("max_accel_dps2", max_accel_dps2, UINT32_MAX),
                      (Od.MAX_DECELERATION, 0): ("max_decel_dps2", max_decel_dps2, UINT32_MAX),
                      (Od.PROFILE_ACCELERATION, 0): ("profile_accel_dps2", profile_accel_dps2,
                                                     UINT32_MAX),
                      (Od.PROFILE_DECELERATION, 0): ("profile_accel_dps2", profile_accel_dps2,
                                                     UINT32_MAX),
                      (Od.QUICK_STOP_DECELERATION, 0): ("quick_stop_decel_dps2",
                                                        quick_stop_decel_dps2, UINT32_MAX)},
        }
        f = self.factors
        self._initial = {
            **self._unit_objects(),
            (Od.GEAR_RATIO, 1): f.gear_motor_revs, (Od.GEAR_RATIO, 2): f.gear_shaft_revs,
            (Od.SI_UNIT_VELOCITY, 0): f.velocity_si,
            (Od.SI_UNIT_ACCELERATION, 0): f.acceleration_si,
            (Od.POSITION_WINDOW, 0): self._fit("position_window_deg", position_window_deg,
                                               self.units.deg_to_counts, UINT32_MAX),
            (Od.POSITION_ENCODER_RESOLUTION, 1): f.encoder_increments,
            (Od.POSITION_ENCODER_RESOLUTION, 2): f.motor_revolutions,
            (Od.CONSUMER_HEARTBEAT, 1): (controller_node_id << 16)
            | self._fit("watchdog_s", watchdog_s, lambda s: round(s * 1000), UINT16_MAX),
            (Od.IDENTITY, 4): serial_number,
        }
        if self._initial[(Od.MAX_PROFILE_VELOCITY, 0)] > INT32_MAX:
            raise ValueError(f"max_rate_dps = {max_rate_dps} deg/s does not fit 0x60FF "
                             f"(INTEGER32) in these velocity units")
        self._lock = threading.RLock()
        self._state = State.NOT_READY_TO_SWITCH_ON
        self._mode = 0
        self._controlword = 0
        self._fault: DriveErrorCode | None = None
        self._error_register = 0
        self._after_standstill: State | None = None
        self._velocity_units = 0
        self._position_counts = 0
        self._speed_zero_since: float | None = 0.0
        self._in_window_since: float | None = None
        self._speed_zero = True
        self._target_reached = False
        self._set_point_ack = False           # PP: statusword bit 12
        self._pp_target_deg: float | None = None
        self._pp_corrections = 0
        self._in_position_since: float | None = None
        # heartbeat consumer (0x1016:1): producer id, time, last reception (monotonic). A
        # real drive receives on its CAN controller whatever its motion task is doing, so
        # the reception takes a lock of its own, never the motion lock a tick holds
        self._hb_lock = threading.Lock()
        self._hb_producer = 0
        self._hb_time_s = 0.0
        self._hb_last: float | None = None
        self.watchdog_trips: list[WatchdogTrip] = []
        self.emcy_sent: list[tuple[float, int]] = []  # (stand time, code)
        self._network: canopen.Network | None = None
        self._node: canopen.LocalNode | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._tick_s = 0.01
        self._tpdo_last: dict[int, float] = {}
        self._tpdo_last_paused: dict[int, float] = {}  # stepped clock paused: real time
        self._tpdo_values: dict[int, list[int]] = {}
        #: synchronous RPDOs received, by communication parameter index: (index, sub,
        #: data) written at the next SYNC (_on_rpdo)
        self._rpdo_pending: dict[int, list[tuple[int, int, bytes]]] = {}
        #: mode code -> what entering Operation enabled or a new set-point does in it
        self._mode_handlers = {PROFILE_VELOCITY.code: self._pv_follow_target,
                               PROFILE_POSITION.code: self._pp_hold}
        self._initial[(Od.SUPPORTED_DRIVE_MODES, 0)] = sum(
            MODES[code].supported_bit for code in self._mode_handlers)

    def _unit_objects(self, units: DriveUnits | None = None,
                      saturate: bool = False) -> dict[tuple[int, int], int]:
        """Every velocity and acceleration object in `units` (default: the present ones).
        `saturate`: a value its object cannot hold takes the object's nearest (a change of
        the factor group, see _change_units); otherwise it is the twin's own error."""
        u = self.units if units is None else units
        convert = {"velocity": u.dps_to_velocity, "accel": u.dps2_to_accel}
        if saturate:
            return {key: min(max(convert[kind](value), 0), limit)
                    for kind, table in self._deg_values.items()
                    for key, (name, value, limit) in table.items()}
        return {key: self._fit(name, value, convert[kind], limit)
                for kind, table in self._deg_values.items()
                for key, (name, value, limit) in table.items()}

    #: the factor group's objects -> the UnitFactors field each sub-index sets
    _FACTOR_FIELDS: dict[tuple[int, int], str] = {
        (Od.POSITION_ENCODER_RESOLUTION, 1): "encoder_increments",
        (Od.POSITION_ENCODER_RESOLUTION, 2): "motor_revolutions",
        (Od.GEAR_RATIO, 1): "gear_motor_revs", (Od.GEAR_RATIO, 2): "gear_shaft_revs",
        (Od.SI_UNIT_VELOCITY, 0): "velocity_si", (Od.SI_UNIT_ACCELERATION, 0): "acceleration_si",
        (Od.VELOCITY_FACTOR, 1): "velocity_factor", (Od.VELOCITY_FACTOR, 2): "velocity_factor",
        (Od.ACCELERATION_FACTOR, 1): "acceleration_factor",
        (Od.ACCELERATION_FACTOR, 2): "acceleration_factor",
    }

    def _change_units(self, index: int, sub: int, code: int) -> None:
        """A factor-group object written (0x608F, 0x6091, 0x6096, 0x6097, 0x60A9,
        0x60AA): new units, applied as a drive applies them; the limits keep their meaning
        in deg/s. Refused while the power stage is on (abort 0x08000022), or with a value
        that gives no whole positive number of increments a turn (0x06090030).

        Issue 41: the factor group is consistent at every step. A write is checked whole
        before anything changes (a refused one leaves the twin's units and the OD as they
        were: it used to take the new factors but leave the OD behind, so a gear ratio
        answered with a general error 0x08000000 made the next write of 0x6091, back to
        1:1, fail too, until Reset Node), and a limit its UNSIGNED16/32 object cannot hold
        in the new units (0x606D's 0.02 deg/s at twice the increments) takes the object's
        nearest value: the ratio itself is valid (0x6091: motor revolutions per shaft
        revolutions), and keeping the limits in deg/s is the twin's own rule, not the
        profile's, so it must not refuse a ratio for it."""
        if self._state.power_stage_on:
            raise SdoAbortedError(ABORT_DEVICE_STATE)
        field = self._FACTOR_FIELDS[(index, sub)]
        f = self.factors
        value: Any = code   # a field of UnitFactors: its ratio or a code
        if field in ("velocity_factor", "acceleration_factor"):
            old = getattr(f, field)
            value = (code, old[1]) if sub == 1 else (old[0], code)
        new = dataclasses.replace(f, **{field: value})
        try:
            units = new.drive_units(apply_factors=True)
            if units.counts_per_rev <= 0:
                raise ValueError("no increments")
            values = self._unit_objects(units, saturate=True)
        except (ValueError, ZeroDivisionError, OverflowError) as e:
            raise SdoAbortedError(ABORT_VALUE_RANGE) from e
        self.factors, self.units = new, units      # all at once, once nothing can fail
        for (i, s), v in values.items():
            self._put(i, s, v)

    # -- NMT (CiA 301 7.3.2) and the PDOs (CiA 301 7.2.2) --------------------------------
    def _load_defaults(self, first: int, last: int) -> None:
        """Objects first..last back to their power-on values (the EDS's, then the twin's)."""
        node = self._node
        assert node is not None
        for index in [i for i in node.data_store if first <= i <= last]:
            del node.data_store[index]
        if first <= Od.POSITION_ENCODER_RESOLUTION <= last:
            self.factors, self.units = self._factors0, self._factors0.drive_units()
        for (index, sub), value in self._initial.items():
            if first <= index <= last:
                self._put(index, sub, value)
        if first <= 0x1800 <= last and self._tpdo_event_timer_ms is not None:
            for n in range(4):  # e.g. 0: TPDOs only on change
                with contextlib.suppress(KeyError):
                    self._put(0x1800 + n, 5, self._tpdo_event_timer_ms)

    def _read_pdos(self) -> None:
        """Every PDO's communication and mapping parameters as the OD holds them now."""
        node = self._node
        assert node is not None
        for pdo in _maps(node.tpdo).values():
            pdo.read(from_od=False)
        for pdo in _maps(node.rpdo).values():
            self._reload_rpdo(pdo)
        timers = [m.event_timer for m in _maps(node.tpdo).values() if m.enabled and m.event_timer]
        self._tick_s = min(timers, default=10) / 1000.0
        self._sync_count = 0

    def _boot_up(self) -> None:
        """Initialisation done: boot-up message, then pre-operational on its own, with
        the heartbeat producer (0x1017) started (CiA 301 7.3.2.2)."""
        node = self._node
        assert node is not None
        node.nmt._state = NMT_INITIALISING
        node.nmt.stop_heartbeat()
        node.nmt.send_command(NMT_RESET_NODE)  # canopen sends the boot-up message here
        node.nmt._state = NMT_PRE_OP
        # the boot-up message is the first heartbeat: the next one follows a period later
        # (canopen's producer would send one at once, and a client waiting for the
        # boot-up, NmtMaster.wait_for_bootup, would see that one instead)
        period_ms = self._get(Od.PRODUCER_HEARTBEAT)
        if period_ms:
            timer = threading.Timer(period_ms / 1000.0, self._start_heartbeat, (period_ms,))
            timer.daemon = True
            timer.start()

    def _start_heartbeat(self, period_ms: int) -> None:
        with self._lock:
            node = self._node
            if node is not None and not self._stop.is_set() \
                    and node.nmt._state != NMT_INITIALISING:
                node.nmt.start_heartbeat(period_ms)

    def _boot_up_if_running(self) -> None:
        with self._lock:
            if self._node is not None and self._network is not None \
                    and not self._stop.is_set():
                self._boot_up()

    def _on_nmt(self, cmd: int) -> None:
        """An NMT command from the master. Stopped and the resets, while the power stage
        is on, take the abort-connection reaction 0x6007 (CiA 402); a reset then boots up
        again; SDO is not served in Stopped (CiA 301)."""
        node = self._node
        if node is None:
            return
        with self._lock:
            if cmd != NMT_START:   # out of Operational: no SYNC actuates what waited
                self._rpdo_pending.clear()
            if cmd in (NMT_STOP, NMT_RESET_NODE, NMT_RESET_COMM) \
                    and node.nmt._state != NMT_STOPPED:
                self._abort_connection(f"NMT command {cmd}", emcy=cmd == NMT_STOP)
            if cmd == NMT_START:
                node.nmt._state = NMT_OPERATIONAL
            elif cmd == NMT_STOP:
                node.nmt._state = NMT_STOPPED
            elif cmd == NMT_PRE_OPERATIONAL:
                node.nmt._state = NMT_PRE_OP
            elif cmd in (NMT_RESET_NODE, NMT_RESET_COMM):
                if cmd == NMT_RESET_NODE:  # the application area back to power-on values
                    self._reset_application()
                self._load_defaults(0x1000, 0x1FFF)  # the communication area
                self._read_pdos()
                self._configure_consumer(self._get(Od.CONSUMER_HEARTBEAT, 1))
                node.nmt._state = NMT_INITIALISING
                node.nmt.stop_heartbeat()
                # a drive takes a while to initialise: a client that sends the reset
                # and then waits for the boot-up (canopen's wait_for_bootup) sees it
                timer = threading.Timer(RESET_BOOT_S, self._boot_up_if_running)
                timer.daemon = True
                timer.start()
                return
            else:
                return
            node.nmt.update_heartbeat()

    def _reset_application(self) -> None:
        """Reset node: 0x2000-0x9FFF to power-on values, the 402 state machine restarts
        (transitions 0, 1); an axis still driven is let go."""
        if self._state.power_stage_on and self._after_standstill is None:
            self._ramp_to_zero(Ramp.COAST)
        self._mode = 0
        self._controlword = 0
        self._fault, self._error_register = None, 0
        self._pp_target_deg = None
        self._load_defaults(0x2000, 0x9FFF)
        if self._state.power_stage_on:
            self._after_standstill = State.SWITCH_ON_DISABLED
        else:
            self._state, self._after_standstill = State.SWITCH_ON_DISABLED, None

    def _pdo_parameter(self, index: int, sub: int, value: int, data: bytes) -> None:
        """A PDO communication (0x1400/0x1800) or mapping (0x1600/0x1A00) parameter
        written: checked as CiA 301 7.5.2.35-38 says, then in effect at once.

        The mapping (7.5.2.36 RPDO / 7.5.2.38 TPDO mapping parameter) is changed by the
        procedure those sections give: the PDO made not valid (COB-ID bit 31), sub-index 0
        set to 0, the entries written, sub-index 0 set to their count, the PDO made valid
        again. Any sub-index written while the PDO is valid, and an entry written while
        sub-index 0 is not 0, is refused with 0x08000022 ("data cannot be transferred or
        stored to the application because of the present device state"; CiA 301's own
        text was not at hand, and the open stacks differ: CANopenNode answers 0x06010000,
        Lely 0x06090030, so no client can rely on one code; the twin keeps the one it gave
        for the entries already). An entry naming an object that does not exist, is not
        mappable, or with a length other than the object's (0x6041, 16 bits, as 32) is
        refused with 0x06040041 "object cannot be mapped to the PDO" (7.5.2.36 step 3;
        CANopenNode's PDOconfigMap alike); a count whose entries exceed the PDO's 64 bits
        or the entries there are with 0x06040042 (step 4)."""
        node = self._node
        assert node is not None
        tx = index >= 0x1800
        base = 0x1800 if tx else 0x1400
        mapping = (index & 0x0200) != 0
        number = (index - base - (0x200 if mapping else 0)) + 1
        pdo = _maps(node.tpdo if tx else node.rpdo).get(number)
        if pdo is None:
            return
        if not mapping and sub == 1:
            if not value & PDO_NOT_VALID and pdo.enabled and value & 0x7FF != pdo.cob_id:
                raise SdoAbortedError(ABORT_VALUE_RANGE)  # a valid PDO's COB-ID stays
        elif not mapping and sub == 2 and 241 <= value <= 251:
            raise SdoAbortedError(ABORT_VALUE_RANGE)  # reserved transmission types
        elif mapping and pdo.enabled:
            raise SdoAbortedError(ABORT_DEVICE_STATE)  # remap only a disabled PDO
        elif mapping and sub == 0:
            bits = 0
            for n in range(1, value + 1):
                try:
                    entry = self._get(index, n)
                except KeyError as e:        # more entries than the PDO has
                    raise SdoAbortedError(ABORT_PDO_LENGTH) from e
                bits += self._mapped_bits(entry)
            if bits > 64:
                raise SdoAbortedError(ABORT_PDO_LENGTH)
        elif mapping and self._get(index, 0) != 0:
            raise SdoAbortedError(ABORT_DEVICE_STATE)  # sub-index 0 to 0 first
        elif mapping and value:
            self._mapped_bits(value)
        node.data_store.setdefault(index, {})[sub] = data  # stored now, read back below
        if tx:
            pdo.read(from_od=False)
            self._tpdo_values.pop(number, None)
        else:
            self._reload_rpdo(pdo)

    def _mapped_bits(self, entry: int) -> int:
        """A mapping entry's length, once its object is found mappable with that length
        (abort 0x06040041 otherwise; see _pdo_parameter)."""
        index, sub, bits = entry >> 16, (entry >> 8) & 0xFF, entry & 0xFF
        node = self._node
        assert node is not None
        try:
            obj = node.object_dictionary[index]
            var = obj if isinstance(obj, ODVariable) else obj[sub]
        except KeyError as e:
            raise SdoAbortedError(ABORT_NOT_MAPPABLE) from e
        if (isinstance(obj, ODVariable) and sub != 0) or not var.pdo_mappable \
                or bits != len(var):
            raise SdoAbortedError(ABORT_NOT_MAPPABLE)
        return bits

    def _reload_rpdo(self, pdo: PdoMap) -> None:
        """Read an RPDO's parameters and listen on its (new) COB-ID, if valid (data it
        received for the next SYNC are dropped: its parameters changed)."""
        self._rpdo_pending.pop(pdo.com_record.od.index, None)
        network = self._network
        if network is not None and pdo.cob_id is not None:
            with contextlib.suppress(KeyError, ValueError):
                network.unsubscribe(pdo.cob_id, pdo.on_message)
        pdo.read(from_od=False)
        if network is not None:
            pdo.subscribe()

    def _on_rpdo(self, pdo: PdoMap) -> None:
        """An RPDO received (only when operational): its objects written as an SDO write
        would. Asynchronous (transmission type 254/255) at once; synchronous (0-240) at
        the next SYNC: CiA 301 7.2.2.3 (PDO transmission types) and 0x1400 sub 2, a
        synchronous RPDO's data are actuated with the next SYNC received; the newest
        received before it wins (Lely's rpdo.c keeps the frame "to be processed after the
        next SYNC object" the same way). Issue 41: the twin applied every RPDO at once."""
        node = self._node
        if node is None or node.nmt._state != NMT_OPERATIONAL:
            return
        writes = [(var.index, var.subindex, bytes(var.get_data())) for var in pdo.map]
        tt = pdo.trans_type
        if tt is not None and tt <= 240:
            with self._lock:
                self._rpdo_pending[pdo.com_record.od.index] = writes
            return
        self._apply_rpdo(writes)

    def _apply_rpdo(self, writes: list[tuple[int, int, bytes]]) -> None:
        node = self._node
        assert node is not None
        for index, sub, data in writes:
            with contextlib.suppress(SdoAbortedError):
                node.set_data(index, sub, data)

    def _on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:
        """SYNC: the synchronous RPDOs received since the last one actuated, then the
        synchronous TPDOs (type 0: acyclic, 1-240: every n-th SYNC) sent (CANopenNode's
        order: CO_process_SYNC, CO_process_RPDO, CO_process_TPDO)."""
        node = self._node
        if node is None or node.nmt._state != NMT_OPERATIONAL:
            return
        with self._lock:
            pending = [self._rpdo_pending.pop(i) for i in sorted(self._rpdo_pending)]
            for writes in pending:
                self._apply_rpdo(writes)
            self._sync_count += 1
            for pdo in _maps(node.tpdo).values():
                tt = pdo.trans_type
                if pdo.enabled and tt is not None and 1 <= tt <= 240 \
                        and self._sync_count % tt == 0:
                    self._send_tpdo(pdo)

    def _send_tpdo(self, pdo: PdoMap) -> list[int]:
        values = [self._live(v.index) if v.index in _LIVE else self._get(v.index, v.subindex)
                  for v in pdo.map]
        for var, value in zip(pdo.map, values, strict=True):
            var.raw = value
        pdo.transmit()
        return values

    @staticmethod
    def _fit(key: str, value: float, convert: Callable[[float], int], limit: int) -> int:
        units = convert(value)
        if not 0 <= units <= limit:
            raise ValueError(f"drive twin {key} = {value} is {units} drive units, "
                             f"outside its object's range 0..{limit}")
        return units

    # -- life cycle ---------------------------------------------------------------
    def start(self) -> DriveTwin:
        """Join the bus, boot (boot-up message, then pre-operational with heartbeats)."""
        if self._network is not None:
            return self
        network = canopen.Network()
        network.NOTIFIER_CYCLE = 0.1  # disconnect() waits up to one cycle
        node = canopen.LocalNode(self.node_id, str(self.eds_path))
        # the twin's own reactions to NMT commands and SDO requests (CiA 301)
        node._write_callbacks.remove(node.nmt.on_write)
        node.nmt = _DriveNmt(self.node_id, node, self)
        node.add_write_callback(node.nmt.on_write)
        serve_sdo = node.sdo.on_request
        node.sdo.on_request = lambda can_id, data, ts: (  # type: ignore[method-assign]
            None if node.nmt._state == NMT_STOPPED else serve_sdo(can_id, data, ts))
        # the EDS declares 0x1016:1; a twin configured otherwise says so in its own OD
        consumer_heartbeat = node.object_dictionary[Od.CONSUMER_HEARTBEAT]
        assert isinstance(consumer_heartbeat, ODArray)  # the EDS's 0x1016 (ObjectType 0x8)
        consumer_heartbeat[1].default = self._initial[(Od.CONSUMER_HEARTBEAT, 1)]
        network.add_node(node)
        self._network, self._node = network, node
        self._load_defaults(0x1000, 0xFFFF)
        node.add_read_callback(self._on_read)
        node.add_write_callback(self._on_write)
        network.connect(interface=self.interface, channel=self.channel, **self.bus_options)
        for pdo in _maps(node.rpdo).values():
            pdo.add_callback(self._on_rpdo)
        network.subscribe(COB_SYNC, self._on_sync)
        self._read_pdos()
        self._configure_consumer(self._get(Od.CONSUMER_HEARTBEAT, 1))
        with self._lock:
            self._state = State.SWITCH_ON_DISABLED  # transitions 0 and 1: self-test passed
        self._boot_up()
        self._stop.clear()
        if self._stepped:
            node.add_write_callback(self._note_write)
            self._leave = self._stepped_clock.join(self)
        self._thread = threading.Thread(
            target=self._run_watchdog if self._stepped else self._run,
            name=f"drive-twin-{self.axis}", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Leave the bus (the table keeps whatever ramp it was on)."""
        self._stop.set()
        if self._leave is not None:
            self._leave()
            self._leave = None
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        if self._network is not None:
            try:
                if self._node is not None:
                    self._node.nmt.stop_heartbeat()
                self._network.disconnect()
            finally:
                self._network = None

    def silence_heartbeat(self) -> None:
        """Fault hook: the drive's heartbeat producer dies while its TPDOs go on (the fault
        campaign's "drive heartbeat lost")."""
        if self._node is not None:
            self._node.nmt.stop_heartbeat()

    def settle_after_controller(self, limit_s: float = 15.0) -> None:
        """A real drive outlives the controller that left it: wait (real time, at most
        `limit_s`) until a drive left with its power stage on has let its heartbeat
        watchdog act, so the stand shows what the table would do."""
        # its watchdog time, plus what the twin's own starvation may add (_was_starved)
        deadline = time.monotonic() + min(limit_s, self._hb_time_s + 5.0)
        while self._thread is not None and time.monotonic() < deadline:
            with self._lock:
                if not self._state.power_stage_on or not self._hb_producer:
                    return
            time.sleep(0.02)

    def __enter__(self) -> DriveTwin:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- what tests and the simulated bench look at -------------------------------
    @property
    def state(self) -> State:
        with self._lock:
            return self._state

    @property
    def fault(self) -> DriveErrorCode | None:
        with self._lock:
            return self._fault

    @property
    def watchdog_s(self) -> float:
        """The heartbeat-consumer time now configured (0x1016:1), s of real time."""
        with self._lock:
            return self._hb_time_s

    @property
    def servo_tolerance_dps(self) -> float:
        """The velocity window 0x606D, deg/s."""
        return self.units.velocity_to_dps(self._get(Od.VELOCITY_WINDOW))

    def inject(self, fault: DriveErrorCode | int) -> None:
        """An internal fault: EMCY, then the fault reaction (0x605E) and the Fault state."""
        if isinstance(fault, int):
            fault = DriveErrorCode(fault, describe_error(fault))
        with self._lock:
            self._raise_fault(fault)

    # -- object dictionary access -------------------------------------------------
    def _put(self, index: int, sub: int, value: int) -> None:
        assert self._node is not None
        var = self._odvar(index, sub)
        self._node.data_store.setdefault(index, {})[sub] = var.encode_raw(value)

    def _get(self, index: int, sub: int = 0) -> int:
        assert self._node is not None
        return _integer(self._odvar(index, sub), self._node.get_data(index, sub))

    def _odvar(self, index: int, sub: int) -> ODVariable:
        assert self._node is not None
        obj = self._node.object_dictionary[index]
        return obj if isinstance(obj, ODVariable) else obj[sub]

    def _on_read(self, index: int, subindex: int, od: ODVariable) -> int | None:
        if index not in _LIVE:
            return None
        with self._lock:
            return self._live(index)

    def _live(self, index: int) -> int:
        if index == Od.STATUSWORD:
            return self._statusword()
        if index == Od.MODES_OF_OPERATION_DISPLAY:
            return self._mode
        if index == Od.POSITION_ACTUAL:
            return self._position_counts
        if index == Od.VELOCITY_ACTUAL:
            return self._velocity_units
        if index == Od.ERROR_CODE:
            return self._fault.code if self._fault else 0
        if index == Od.ERROR_REGISTER:
            return self._error_register
        raise KeyError(index)

    def _statusword(self) -> int:
        sw = self._state.bits | Sw.REMOTE
        if self._state not in (State.NOT_READY_TO_SWITCH_ON, State.SWITCH_ON_DISABLED,
                               State.FAULT):
            sw |= Sw.VOLTAGE_ENABLED
        if self._target_reached:
            sw |= Sw.TARGET_REACHED
        zero_bit = MODES[self._mode].speed_zero_bit if self._mode in MODES else Sw.SPEED_ZERO
        if zero_bit is not None and self._speed_zero:
            sw |= zero_bit
        if self._mode == PROFILE_POSITION.code and self._set_point_ack:
            sw |= Sw.SET_POINT_ACKNOWLEDGE
        return sw

    def _on_write(self, index: int, subindex: int, od: ODVariable, data: bytes) -> None:
        """SDO writes from the controller (runs in the CAN receive thread)."""
        value = _integer(od, data)
        with self._lock:
            if index == Od.CONTROLWORD:
                self._on_controlword(value)
            elif index == Od.MODES_OF_OPERATION:
                if value != 0 and value not in self._mode_handlers:
                    raise SdoAbortedError(ABORT_VALUE_RANGE)
                changed, self._mode = value != self._mode, value
                if changed and value:  # the new mode takes over from its own set-point
                    self._mode_handlers[value]()
            elif index == Od.TARGET_VELOCITY:
                if abs(value) > self._get(Od.MAX_PROFILE_VELOCITY):
                    raise SdoAbortedError(ABORT_VALUE_TOO_HIGH)
            elif index in (Od.PROFILE_ACCELERATION, Od.PROFILE_DECELERATION,
                           Od.QUICK_STOP_DECELERATION):
                limit = self._get(Od.MAX_ACCELERATION if index == Od.PROFILE_ACCELERATION
                                  else Od.MAX_DECELERATION)
                if value <= 0:
                    raise SdoAbortedError(ABORT_VALUE_TOO_LOW)
                if value > limit:
                    raise SdoAbortedError(ABORT_VALUE_TOO_HIGH)
            elif index == Od.CONSUMER_HEARTBEAT and subindex == 1:
                self._configure_consumer(value)
            elif (index, subindex) in self._FACTOR_FIELDS:
                self._change_units(index, subindex, value)
            elif index in OPTION_CODES:
                if value not in OPTION_CODES[index]:  # reserved or manufacturer specific
                    raise SdoAbortedError(ABORT_VALUE_RANGE)
            elif 0x1400 <= index <= 0x1BFF:
                self._pdo_parameter(index, subindex, value, data)
            mode = MODES.get(self._mode)
            if mode is not None and index == mode.target and mode.setpoint_on_write:
                self._mode_handlers[mode.code](value)  # a new set-point of the active mode

    # -- state machine --------------------------------------------------------------
    def _on_controlword(self, cw: int) -> None:
        previous = self._controlword
        self._state_machine(cw)
        if self._state is State.OPERATION_ENABLED and self._after_standstill is None \
                and (cw ^ previous) & Cw.HALT:
            self._halt_changed()

    @property
    def _halted(self) -> bool:
        return bool(self._controlword & Cw.HALT)

    def _halt_changed(self) -> None:
        """Controlword bit 8 (CiA 402 halt): set, the axis stops with the ramp 0x605D
        says and stays in Operation enabled; cleared, it takes up its set-point again
        (PV: 0x60FF; PP: the move under way)."""
        if self._halted:
            self._ramp_to_zero(HALT_OPTIONS.get(self._get(Od.HALT_OPTION), Ramp.PROFILE))
        elif self._mode == PROFILE_VELOCITY.code:
            self._pv_follow_target()
        elif self._mode == PROFILE_POSITION.code and self._pp_target_deg is not None:
            self._pp_move(self.model.angle_deg, self._pp_target_deg, correction=True)

    def _state_machine(self, cw: int) -> None:
        rising_reset = bool(cw & Cw.FAULT_RESET and not self._controlword & Cw.FAULT_RESET)
        previous, self._controlword = self._controlword, cw
        if self._mode == PROFILE_POSITION.code:
            self._pp_handshake(cw, previous)
        if rising_reset:
            if self._state is State.FAULT:
                self._fault_reset()
            return
        cmd = decode_command(cw)
        if cmd is None:
            return
        arc = transition(self._state, cmd, self._get(Od.QUICK_STOP_OPTION))
        if arc is None:
            return
        n = arc.number
        if n in (34, 4, 16):
            self._after_standstill = None
            self._state = State.OPERATION_ENABLED
            handler = self._mode_handlers.get(self._mode)
            if handler is not None:
                handler()  # a drive follows the set-point it holds: the driver zeroes it first
        elif n in (5, 8):
            option = Od.DISABLE_OPERATION_OPTION if n == 5 else Od.SHUTDOWN_OPTION
            ramp = SLOW_DOWN_OPTIONS.get(self._get(option), Ramp.COAST)
            self._stop_then(ramp, arc.target)
        elif n in (9, 12):
            self._stop_then(Ramp.COAST, arc.target)
        elif n == 11:
            self._quick_stop()
        else:  # 2, 3, 6, 7, 10: the power stage is off, nothing moves
            self._state = arc.target

    def _quick_stop(self) -> None:
        """Transition 11: ramp as 0x605A says, then stay or go to Switch on disabled."""
        ramp, end = QUICK_STOP_OPTIONS.get(self._get(Od.QUICK_STOP_OPTION),
                                           QUICK_STOP_OPTIONS[2])
        self._state = State.QUICK_STOP_ACTIVE
        self._ramp_to_zero(ramp)
        self._after_standstill = end if end is not State.QUICK_STOP_ACTIVE else None

    def _stop_then(self, ramp: Ramp, target: State) -> None:
        """Ramp to rest, then enter `target` (at once when coasting: the stage opens now)."""
        self._ramp_to_zero(ramp)
        if ramp is Ramp.COAST or self._standing_still():
            self._state = target
            self._after_standstill = None
        else:
            self._after_standstill = target

    def _raise_fault(self, fault: DriveErrorCode) -> None:
        self._send_emcy(fault)
        if self._state in (State.FAULT, State.FAULT_REACTION_ACTIVE):
            return  # the first fault stays the one in 0x603F
        self._fault = fault
        self._error_register |= fault.register
        if self._state.power_stage_on:
            ramp = FAULT_REACTION_OPTIONS.get(self._get(Od.FAULT_REACTION_OPTION),
                                              Ramp.QUICK_STOP)
            self._state = State.FAULT_REACTION_ACTIVE  # transition 13
            self._ramp_to_zero(ramp)
            self._after_standstill = State.FAULT  # transition 14
            if self._standing_still():
                self._state, self._after_standstill = State.FAULT, None
        else:
            self._state = State.FAULT

    def _fault_reset(self) -> None:
        """Transition 15: clear the fault, EMCY 'error reset', Switch on disabled."""
        self._fault = None
        self._error_register = 0
        self._state = State.SWITCH_ON_DISABLED
        if self._node is not None and self._network is not None:
            self._node.emcy.reset(0)

    def _send_emcy(self, fault: DriveErrorCode) -> None:
        self.emcy_sent.append((self.clock.now(), fault.code))
        if self._node is not None and self._network is not None:
            self._node.emcy.send(fault.code, self._error_register | fault.register)

    # -- motion -----------------------------------------------------------------------
    def _pv_follow_target(self, target_units: int | None = None) -> None:
        """Profile velocity: ramp to 0x60FF with 0x6083 up and 0x6084 down (CiA 402 PV)."""
        if self._state is not State.OPERATION_ENABLED or self._after_standstill is not None \
                or self._halted:
            return
        if target_units is None:
            target_units = self._get(Od.TARGET_VELOCITY)
        u = self.units
        self._command_profile(u.velocity_to_dps(target_units),
                              u.accel_to_dps2(self._get(Od.PROFILE_ACCELERATION)),
                              u.accel_to_dps2(self._get(Od.PROFILE_DECELERATION)))

    def _pp_hold(self, target_units: int | None = None) -> None:
        """Profile position on entry or enable: hold where the axis is (no set-point yet)."""
        self._pp_target_deg = None

    def _pp_handshake(self, cw: int, previous: int) -> None:
        """PP set-point handshake: bit 4 rising takes 0x607A (ack on bit 12), falling clears."""
        if not cw & Cw.NEW_SET_POINT:
            self._set_point_ack = False
            return
        if previous & Cw.NEW_SET_POINT or self._state is not State.OPERATION_ENABLED \
                or self._after_standstill is not None or cw & Cw.HALT:
            return
        m = self.model
        with m.lock:
            t = self.clock.now()
            m.advance_to(t)
            if m.commanded_rate_at(max(t, m.t_s)) != 0.0:
                return  # a move onto a moving axis is not modelled: no acknowledge
            phi = m.angle_deg
        target = self._get(Od.TARGET_POSITION)
        here = wrap_int32(self.units.deg_to_counts(phi))
        step = target if cw & Cw.RELATIVE else wrap_int32(target - here)
        self._pp_move(phi, phi + self.units.counts_to_deg(step))
        self._set_point_ack = True

    def _pp_move(self, phi_deg: float, target_deg: float, correction: bool = False) -> None:
        """A trapezoid (or triangle) from rest at phi to rest at the target, CiA 402 PP."""
        if not correction:
            self._pp_corrections = 0
        u = self.units
        v = u.velocity_to_dps(self._get(Od.PROFILE_VELOCITY_PP))
        a = u.accel_to_dps2(self._get(Od.PROFILE_ACCELERATION))
        d = u.accel_to_dps2(self._get(Od.PROFILE_DECELERATION))
        dist = target_deg - phi_deg
        self._pp_target_deg = target_deg
        self._in_position_since = None
        if dist == 0.0 or v <= 0.0:
            return
        peak = min(v, (2.0 * abs(dist) * a * d / (a + d)) ** 0.5)
        cruise_s = (abs(dist) - peak * peak / (2 * a) - peak * peak / (2 * d)) / peak
        m = self.model
        with m.lock:
            t0 = max(self.clock.now(), m.t_s)
            m.command_rate(t0, peak if dist > 0 else -peak, a)
            m.profile.command(t0 + peak / a + max(cruise_s, 0.0), 0.0, d)

    def _command_profile(self, target_dps: float, accel_dps2: float, decel_dps2: float) -> None:
        """The profile generator (0x6083 up, 0x6084 down): the stand model's ramps."""
        self.model.command_rate(self.clock.now(), target_dps, accel_dps2, decel_dps2)

    def _ramp_to_zero(self, ramp: Ramp) -> None:
        u = self.units
        if ramp is Ramp.PROFILE:
            decel = u.accel_to_dps2(self._get(Od.PROFILE_DECELERATION))
        elif ramp is Ramp.QUICK_STOP:
            decel = u.accel_to_dps2(self._get(Od.QUICK_STOP_DECELERATION))
        elif ramp in (Ramp.CURRENT_LIMIT, Ramp.VOLTAGE_LIMIT):
            # the stand model has no torque: the drive's max deceleration stands for it
            decel = u.accel_to_dps2(self._get(Od.MAX_DECELERATION))
        else:
            decel = self.coast_decel_dps2  # friction alone; the stand model has no coast
        self._command_profile(0.0, decel, decel)

    def _standing_still(self) -> bool:
        t = self.clock.now()
        m = self.model
        return m.commanded_rate_at(t) == 0.0 and m.profile.settle_time_s() <= t \
            and abs(m.rate_dps) <= self._threshold_dps()

    def _threshold_dps(self) -> float:
        return self.units.velocity_to_dps(self._get(Od.VELOCITY_THRESHOLD))

    # -- the tick -----------------------------------------------------------------------
    def _run(self) -> None:
        next_t = time.monotonic()
        while not self._stop.is_set():
            started = time.monotonic()
            try:
                self._watch(next_t)
                self._tick()
            except Exception:  # noqa: BLE001 - a twin must not die silently mid-test
                log.exception("drive twin %s: tick failed", self.axis)
            # the grid, but no burst of ticks to catch up after a late one
            next_t = max(next_t + self._tick_s, started)
            self._stop.wait(max(0.0, next_t - time.monotonic()))

    # -- the co-simulation (sims/clock.py SteppedClock) ----------------------------------
    @property
    def _stepped_clock(self) -> SteppedClock:
        """The co-simulation's clock: reached only on a stepped stand (self._stepped)."""
        assert isinstance(self.clock, SteppedClock)
        return self.clock

    def next_event_s(self, t_s: float) -> float:
        with self._lock:
            busy = (t_s < self._busy_until_s or self._after_standstill is not None
                    or self._state is State.QUICK_STOP_ACTIVE
                    or (self._state is State.OPERATION_ENABLED and not self._target_reached)
                    or t_s < self.model.profile.settle_time_s() + ACTIVE_S)
        period = max(FINE_TICK_S, self._tick_s) if busy else max(STEADY_TICK_S, self._tick_s)
        return (math.floor(t_s / period + 1e-9) + 1) * period

    def advance(self, t_s: float) -> None:
        try:
            self._tick(t_s)
        except Exception:  # noqa: BLE001 - a twin must not die silently mid-test
            log.exception("drive twin %s: tick failed", self.axis)

    def settled(self, t_s: float, final: bool) -> bool:
        """Every TPDO sent so far consumed by the controller (each stamped at its tick)."""
        return self._stepped_clock.backlog(self._can_name) == 0

    def _note_write(self, index: int, subindex: int, od: ODVariable, data: bytes) -> None:
        self._busy_until_s = self.clock.now() + ACTIVE_S

    def _run_watchdog(self) -> None:
        """Stepped clock: the thread keeps only the heartbeat watchdog (real time), and
        ticks in real time while the clock is paused (the bench opening or closing: the
        stand stands still, but the controller still hears the drive's TPDOs)."""
        next_t = time.monotonic() + self._tick_s
        while not self._stop.wait(max(0.0, next_t - time.monotonic())):
            started = time.monotonic()
            self._watch(next_t)
            if not self.clock.running:
                try:
                    self._tick(self.clock.now(), gate_s=time.monotonic())
                except Exception:  # noqa: BLE001 - a twin must not die silently mid-test
                    log.exception("drive twin %s: tick failed", self.axis)
            next_t = max(next_t + self._tick_s, started)

    def _tick(self, t_stepped: float | None = None, gate_s: float | None = None) -> None:
        node = self._node
        if node is None:
            return
        with self._lock:
            t = self.clock.now() if t_stepped is None else t_stepped
            with self.model.lock:
                self.model.advance_to(t)
                w = self.model.rate_dps
                phi = self.model.angle_deg
            self._velocity_units = self.units.dps_to_velocity(w)
            self._position_counts = wrap_int32(self.units.deg_to_counts(phi))
            self._update_motion_bits(t, w)
            if self._after_standstill is not None and self._standing_still():
                self._state, self._after_standstill = self._after_standstill, None
            if node.nmt.state != "OPERATIONAL":
                return
            now = gate_s if gate_s is not None else \
                time.monotonic() if t_stepped is None else t_stepped
            book = self._tpdo_last_paused if gate_s is not None else self._tpdo_last
            for n, pdo in _maps(node.tpdo).items():
                # CiA 301: types 254/255 send on an event: the event timer's expiry, or,
                # with the timer at 0, a change of the mapped data (nothing at rest)
                period = (pdo.event_timer or 0) / 1000.0
                if not pdo.enabled or (period and now - book.get(n, -1e9) <
                                       period - 0.5 * self._tick_s):
                    continue
                if pdo.trans_type not in (254, 255):
                    continue  # synchronous: sent on SYNC (_on_sync)
                values = [self._live(v.index) if v.index in _LIVE else
                          self._get(v.index, v.subindex) for v in pdo.map]
                if not period and values == self._tpdo_values.get(n):
                    continue
                self._tpdo_values[n] = self._send_tpdo(pdo)
                if self._stepped and len(pdo.map):
                    self._stepped_clock.sent(self._can_name, 1)
                book[n] = now

    def _update_motion_bits(self, t: float, w: float) -> None:
        """Statusword bits 12 (speed 0) and 10 (target reached), on stand time (CiA 402 PV)."""
        if abs(w) <= self._threshold_dps():
            if self._speed_zero_since is None:
                self._speed_zero_since = t
            self._speed_zero = t - self._speed_zero_since >= \
                self._get(Od.VELOCITY_THRESHOLD_TIME) / 1000.0
        else:
            self._speed_zero_since = None
            self._speed_zero = False
        if self._state is State.OPERATION_ENABLED and self._halted:
            # CiA 402 PV/PP bit 10 with halt = 1: the axis has stopped (velocity 0)
            self._in_window_since = self._in_position_since = None
            self._target_reached = self._speed_zero
        elif self._state is State.OPERATION_ENABLED and self._mode == PROFILE_VELOCITY.code:
            target_dps = self.units.velocity_to_dps(self._get(Od.TARGET_VELOCITY))
            window = self.units.velocity_to_dps(self._get(Od.VELOCITY_WINDOW))
            if abs(w - target_dps) <= window:
                if self._in_window_since is None:
                    self._in_window_since = t
                self._target_reached = t - self._in_window_since >= \
                    self._get(Od.VELOCITY_WINDOW_TIME) / 1000.0
            else:
                self._in_window_since = None
                self._target_reached = False
        elif self._state is State.OPERATION_ENABLED and self._mode == PROFILE_POSITION.code:
            self._in_window_since = None
            target = self._pp_target_deg
            window = self.units.counts_to_deg(self._get(Od.POSITION_WINDOW))
            at_rest = self._standing_still()
            if at_rest and target is not None and abs(self.model.angle_deg - target) \
                    > 0.5 * window and self._pp_corrections < PP_MAX_CORRECTIONS:
                # the position loop: the table's own rate errors left it short or long
                self._pp_corrections += 1
                self._pp_move(self.model.angle_deg, target, correction=True)
                at_rest = False
            if at_rest and (target is None or abs(self.model.angle_deg - target) <= window):
                if self._in_position_since is None:
                    self._in_position_since = t
                self._target_reached = t - self._in_position_since >= \
                    self._get(Od.POSITION_WINDOW_TIME) / 1000.0
            else:
                self._in_position_since = None
                self._target_reached = False
        else:
            self._in_window_since = None
            self._target_reached = self._state is State.QUICK_STOP_ACTIVE and self._speed_zero

    # -- heartbeat consumer (CiA 301 0x1016) and the abort-connection reaction ----------
    def _configure_consumer(self, entry: int) -> None:
        network = self._network
        old = self._hb_producer
        producer, time_ms = (entry >> 16) & 0xFF, entry & 0xFFFF
        if network is not None and old and old != producer:
            network.unsubscribe(COB_HEARTBEAT + old, self._on_controller_heartbeat)
        with self._hb_lock:
            self._hb_producer = producer if time_ms else 0
            self._hb_time_s = time_ms / 1000.0
            self._hb_last = None  # CiA 301: monitoring starts with the next heartbeat received
        if self._hb_producer and network is not None:
            network.subscribe(COB_HEARTBEAT + producer, self._on_controller_heartbeat)

    def _on_controller_heartbeat(self, can_id: int, data: bytearray, timestamp: float) -> None:
        with self._hb_lock:
            self._hb_last = time.monotonic()

    def _watch(self, due_real_s: float) -> None:
        """One look of the heartbeat watchdog, due at `due_real_s` (monotonic): lateness
        is measured once the motion lock is held, so a late wake-up, the last tick's and
        this lock's wait are all forgiven before the controller's silence is judged."""
        with self._lock:
            self._forgive_lateness(due_real_s)
            self._check_watchdog(self.clock.now())

    def _forgive_lateness(self, due_real_s: float) -> None:
        """This thread looks at the watchdog `STARVED_TICKS` periods or more after it was
        due: the host did not run it, or it (or its previous tick) waited that long for a
        lock another thread of this process held (the twin's, the stand's; a loaded
        machine). Either is the twin's own starvation, not the controller's silence: a
        real drive's heartbeat consumer has a timer and a processor of its own."""
        late = time.monotonic() - due_real_s
        if late > STARVED_TICKS * self._tick_s:
            self._was_starved(late)

    def _was_starved(self, late_s: float) -> None:
        """A real drive has a processor of its own; the twin shares the host's with the
        controller. The time the twin itself was not run (a loaded host) is not counted
        as the controller's silence: the controller's heartbeats of that while may still
        sit in the bus queue."""
        with self._hb_lock:
            if self._hb_last is not None:
                self._hb_last = min(self._hb_last + late_s, time.monotonic())

    def _check_watchdog(self, t: float) -> None:
        """Called with the motion lock held, right after `_was_starved` has forgiven the
        twin's own lateness (the thread's wake-up and the previous tick's wait for a lock
        alike), so only the controller's silence trips it."""
        with self._hb_lock:
            last = self._hb_last
            now = time.monotonic()
            if not self._hb_producer or last is None or now - last <= self._hb_time_s:
                return
            self._hb_last = None  # re-armed by the next heartbeat
        reaction = AbortReaction(self._get(Od.ABORT_CONNECTION_OPTION))
        self.watchdog_trips.append(WatchdogTrip(last, now, t, self._hb_time_s, reaction))
        log.warning("drive twin %s: no heartbeat from node %d for %.3f s: %s", self.axis,
                    self._hb_producer, now - last, reaction.name)
        self._abort_connection("heartbeat lost")

    def _abort_connection(self, why: str, emcy: bool = True) -> None:
        """CiA 402 0x6007: the reaction to a lost connection (heartbeat, NMT Stopped, a
        reset) while the power stage is on."""
        reaction = AbortReaction(self._get(Od.ABORT_CONNECTION_OPTION))
        if not self._state.power_stage_on or reaction is AbortReaction.NONE:
            if emcy and why == "heartbeat lost":
                self._send_emcy(HEARTBEAT_LOST)
            return
        log.warning("drive twin %s: %s: %s", self.axis, why, reaction.name)
        if reaction is AbortReaction.FAULT:
            self._raise_fault(HEARTBEAT_LOST)
        elif reaction is AbortReaction.DISABLE_VOLTAGE:
            self._send_emcy(HEARTBEAT_LOST)
            self._stop_then(Ramp.COAST, State.SWITCH_ON_DISABLED)
        else:
            self._send_emcy(HEARTBEAT_LOST)
            if self._state is State.OPERATION_ENABLED:
                self._quick_stop()


def _maps(pdos: PdoBase) -> PdoMaps:
    """A node's TPDO or RPDO maps: canopen types PdoBase.map Optional, TPDO and RPDO set it."""
    assert pdos.map is not None
    return pdos.map


def _si(unit: str | int) -> int:
    """An SI unit object's value: a name of cia402.NAMED_SI_UNITS, or the code itself."""
    return unit if isinstance(unit, int) else NAMED_SI_UNITS[unit]


def _integer(var: ODVariable, data: bytes) -> int:
    """An object's value: every object of the twin's dictionary is an integer (its EDS,
    drivers/profiles), so anything else is a dictionary the twin was not built for."""
    value = var.decode_raw(data)
    if not isinstance(value, int):
        raise TypeError(f"drive twin: object 0x{var.index:04X}.{var.subindex} holds "
                        f"{value!r}, not an integer")
    return value
