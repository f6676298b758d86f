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
import logging
import math
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import canopen
from canopen.objectdictionary import ODVariable
from canopen.sdo import SdoAbortedError

from drivers.cia402 import (
    COB_HEARTBEAT,
    CONTROLLER_NODE_ID,
    DEFAULT_EDS_PATH,
    FAULT_REACTION_OPTIONS,
    HEARTBEAT_LOST,
    INT32_MAX,
    MODES,
    NAMED_SI_UNITS,
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
from sims.stand import AxisModel, SimulatedStand

log = logging.getLogger(__name__)

# SDO abort codes (CiA 301) the twin answers with
ABORT_VALUE_RANGE = 0x06090030
ABORT_VALUE_TOO_HIGH = 0x06090031
ABORT_VALUE_TOO_LOW = 0x06090032
ABORT_DEVICE_STATE = 0x08000022

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


class DriveTwin:
    """The drive of `stand.axes[axis]` as CANopen node `node_id` on `interface:channel`."""

    def __init__(self, stand: SimulatedStand, axis: str, *, interface: str = "virtual",
                 channel: str, node_id: int, eds_path: str | Path = DEFAULT_EDS_PATH,
                 servo_tolerance_dps: float = 0.02, watchdog_s: float = 0.25,
                 controller_node_id: int = CONTROLLER_NODE_ID, counts_per_rev: int = 1 << 20,
                 velocity_unit: str | int = "0.001 inc/s",
                 acceleration_unit: str | int = "inc/s2",
                 gear_ratio: tuple[int, int] = (1, 1), tpdo_event_timer_ms: int | None = None,
                 max_rate_dps: float = 720.0,
                 max_accel_dps2: float = 1000.0, max_decel_dps2: float = 2000.0,
                 profile_accel_dps2: float = 200.0, quick_stop_decel_dps2: float = 1000.0,
                 standstill_dps: float = 0.001, coast_decel_dps2: float = 20.0,
                 position_window_deg: float = 0.001, pp_velocity_dps: float = 10.0,
                 serial_number: int = 0) -> None:
        if not 1 <= node_id <= 127:
            raise ValueError(f"drive twin node_id must be 1..127, got {node_id}")
        self.stand = stand
        self.axis = axis
        self.model: AxisModel = stand.axis(axis)
        self.clock = stand.clock
        self.interface = interface
        self.channel = channel
        self.node_id = node_id
        self._stepped = bool(getattr(self.clock, "stepped", False))
        self._leave: Any = None
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
        # heartbeat consumer (0x1016:1): producer id, time, last reception (monotonic)
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
        #: mode code -> what entering Operation enabled or a new set-point does in it
        self._mode_handlers = {PROFILE_VELOCITY.code: self._pv_follow_target,
                               PROFILE_POSITION.code: self._pp_hold}
        self._initial[(Od.SUPPORTED_DRIVE_MODES, 0)] = sum(
            MODES[code].supported_bit for code in self._mode_handlers)

    def _unit_objects(self) -> dict[tuple[int, int], int]:
        """Every velocity and acceleration object in the present units."""
        convert = {"velocity": self.units.dps_to_velocity, "accel": self.units.dps2_to_accel}
        return {key: self._fit(name, value, convert[kind], limit)
                for kind, table in self._deg_values.items()
                for key, (name, value, limit) in table.items()}

    def _change_units(self, index: int, code: int) -> None:
        """0x60A9/0x60AA written: new units; the limits keep their meaning in deg/s."""
        if self._state is State.OPERATION_ENABLED:
            raise SdoAbortedError(ABORT_DEVICE_STATE)
        f = self.factors
        new = UnitFactors(f.encoder_increments, f.motor_revolutions, f.gear_motor_revs,
                          f.gear_shaft_revs,
                          code if index == Od.SI_UNIT_VELOCITY else f.velocity_si,
                          code if index == Od.SI_UNIT_ACCELERATION else f.acceleration_si)
        try:
            units = new.drive_units()
        except ValueError as e:
            raise SdoAbortedError(ABORT_VALUE_RANGE) from e
        self.factors, self.units = new, units
        for (i, sub), value in self._unit_objects().items():
            self._put(i, sub, value)

    @staticmethod
    def _fit(key: str, value: float, convert: Any, limit: int) -> int:
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
        network.add_node(node)
        self._network, self._node = network, node
        for (index, sub), value in self._initial.items():
            self._put(index, sub, value)
        if self._tpdo_event_timer_ms is not None:  # e.g. 0: TPDOs only on change
            for sub in range(4):
                with contextlib.suppress(KeyError):
                    self._put(0x1800 + sub, 5, self._tpdo_event_timer_ms)
        node.tpdo.read(from_od=True)
        timers = [m.event_timer for m in node.tpdo.map.values() if m.enabled and m.event_timer]
        self._tick_s = min(timers, default=10) / 1000.0
        node.add_read_callback(self._on_read)
        node.add_write_callback(self._on_write)
        self._configure_consumer(self._get(Od.CONSUMER_HEARTBEAT, 1))
        network.connect(interface=self.interface, channel=self.channel)
        node.nmt.send_command(0x81)  # reset node: boot-up message
        with self._lock:
            self._state = State.SWITCH_ON_DISABLED  # transitions 0 and 1: self-test passed
        node.nmt.send_command(0x80)  # pre-operational: heartbeat producer starts (0x1017)
        self._stop.clear()
        if self._stepped:
            node.add_write_callback(self._note_write)
            self._leave = self.clock.join(self)
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

    def _get(self, index: int, sub: int = 0) -> Any:
        assert self._node is not None
        var = self._odvar(index, sub)
        return var.decode_raw(self._node.get_data(index, sub))

    def _odvar(self, index: int, sub: int) -> Any:
        assert self._node is not None
        obj = self._node.object_dictionary[index]
        return obj if isinstance(obj, ODVariable) else obj[sub]

    def _on_read(self, index: int, subindex: int, od: Any) -> int | None:
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

    def _on_write(self, index: int, subindex: int, od: Any, data: bytes) -> None:
        """SDO writes from the controller (runs in the CAN receive thread)."""
        value = od.decode_raw(data)
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
            elif index in (Od.SI_UNIT_VELOCITY, Od.SI_UNIT_ACCELERATION):
                self._change_units(index, value)
            elif 0x1800 <= index <= 0x1803 and subindex in (2, 5) and self._node is not None:
                pdo = self._node.tpdo.map.get(index - 0x1800 + 1)
                if pdo is not None:  # CiA 301: the communication parameters take effect
                    if subindex == 2:
                        pdo.trans_type = value
                    else:
                        pdo.event_timer = value
            mode = MODES.get(self._mode)
            if mode is not None and index == mode.target and mode.setpoint_on_write:
                self._mode_handlers[mode.code](value)  # a new set-point of the active mode

    # -- state machine --------------------------------------------------------------
    def _on_controlword(self, cw: int) -> None:
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
        arc = transition(self._state, cmd)
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
        if self._state is not State.OPERATION_ENABLED or self._after_standstill is not None:
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
                or self._after_standstill is not None:
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
            late = time.monotonic() - next_t
            if late > STARVED_TICKS * self._tick_s:
                self._was_starved(late)
            try:
                self._tick()
            except Exception:  # noqa: BLE001 - a twin must not die silently mid-test
                log.exception("drive twin %s: tick failed", self.axis)
            next_t += self._tick_s
            delay = next_t - time.monotonic()
            if delay < 0:
                next_t = time.monotonic()
                delay = 0.0
            self._stop.wait(delay)

    # -- the co-simulation (sims/clock.py SteppedClock) ----------------------------------
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
        return self.clock.backlog(self._can_name) == 0

    def _note_write(self, index: int, subindex: int, od: Any, data: bytes) -> None:
        self._busy_until_s = self.clock.now() + ACTIVE_S

    def _run_watchdog(self) -> None:
        """Stepped clock: the thread keeps only the heartbeat watchdog (real time), and
        ticks in real time while the clock is paused (the bench opening or closing: the
        stand stands still, but the controller still hears the drive's TPDOs)."""
        while not self._stop.wait(self._tick_s):
            if not self.clock.running:
                try:
                    self._tick(self.clock.now(), gate_s=time.monotonic())
                except Exception:  # noqa: BLE001 - a twin must not die silently mid-test
                    log.exception("drive twin %s: tick failed", self.axis)
            with self._lock:
                self._check_watchdog(self.clock.now())

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
            if t_stepped is None:
                self._check_watchdog(t)
            if node.nmt.state != "OPERATIONAL":
                return
            now = gate_s if gate_s is not None else \
                time.monotonic() if t_stepped is None else t_stepped
            book = self._tpdo_last_paused if gate_s is not None else self._tpdo_last
            for n, pdo in node.tpdo.map.items():
                # CiA 301: types 254/255 send on an event: the event timer's expiry, or,
                # with the timer at 0, a change of the mapped data (nothing at rest)
                period = (pdo.event_timer or 0) / 1000.0
                if not pdo.enabled or (period and now - book.get(n, -1e9) <
                                       period - 0.5 * self._tick_s):
                    continue
                values = [self._live(v.index) if v.index in _LIVE else self._get(v.index)
                          for v in pdo.map]
                if not period and (pdo.trans_type not in (254, 255)
                                   or values == self._tpdo_values.get(n)):
                    continue
                for var, value in zip(pdo.map, values, strict=True):
                    var.raw = value
                pdo.transmit()
                if self._stepped and len(pdo.map):
                    self.clock.sent(self._can_name, 1)
                book[n] = now
                self._tpdo_values[n] = values

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
        if self._state is State.OPERATION_ENABLED and self._mode == PROFILE_VELOCITY.code:
            target = self.units.velocity_to_dps(self._get(Od.TARGET_VELOCITY))
            window = self.units.velocity_to_dps(self._get(Od.VELOCITY_WINDOW))
            if abs(w - target) <= window:
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
        self._hb_producer = producer if time_ms else 0
        self._hb_time_s = time_ms / 1000.0
        self._hb_last = None  # CiA 301: monitoring starts with the next heartbeat received
        if self._hb_producer and network is not None:
            network.subscribe(COB_HEARTBEAT + producer, self._on_controller_heartbeat)

    def _on_controller_heartbeat(self, can_id: int, data: bytes, timestamp: float) -> None:
        with self._lock:
            self._hb_last = time.monotonic()

    def _was_starved(self, late_s: float) -> None:
        """A real drive has a processor of its own; the twin shares the host's with the
        controller. The time the twin itself was not run (a loaded host) is not counted
        as the controller's silence: the controller's heartbeats of that while may still
        sit in the bus queue."""
        with self._lock:
            if self._hb_last is not None:
                self._hb_last = min(self._hb_last + late_s, time.monotonic())

    def _check_watchdog(self, t: float) -> None:
        if not self._hb_producer or self._hb_last is None:
            return
        now = time.monotonic()
        if now - self._hb_last <= self._hb_time_s:
            return
        reaction = AbortReaction(self._get(Od.ABORT_CONNECTION_OPTION))
        self.watchdog_trips.append(WatchdogTrip(self._hb_last, now, t, self._hb_time_s,
                                                reaction))
        log.warning("drive twin %s: no heartbeat from node %d for %.3f s: %s", self.axis,
                    self._hb_producer, now - self._hb_last, reaction.name)
        self._hb_last = None  # re-armed by the next heartbeat
        if not self._state.power_stage_on or reaction is AbortReaction.NONE:
            self._send_emcy(HEARTBEAT_LOST)
        elif reaction is AbortReaction.FAULT:
            self._raise_fault(HEARTBEAT_LOST)
        elif reaction is AbortReaction.DISABLE_VOLTAGE:
            self._send_emcy(HEARTBEAT_LOST)
            self._stop_then(Ramp.COAST, State.SWITCH_ON_DISABLED)
        else:
            self._send_emcy(HEARTBEAT_LOST)
            if self._state is State.OPERATION_ENABLED:
                self._quick_stop()



def _si(unit: str | int) -> int:
    """An SI unit object's value: a name of cia402.NAMED_SI_UNITS, or the code itself."""
    return unit if isinstance(unit, int) else NAMED_SI_UNITS[unit]
