"""The drive twin's CiA 402 state machine: the controlword's commands taken through the
transition table of drivers/cia402.py, the option codes that say how each stop ramps
(0x605A-0x605E), the halt bit, faults with their EMCY and fault reaction, and the
abort-connection reaction 0x6007; the statusword and the other objects the twin
computes when they are read.

What CiA 402 says that canopen's BaseNode402 client does not check is the twin's too:
transition 16 only for quick-stop codes 5-8, the halt bit with 0x605D, every
quick-stop, shutdown, disable-operation and fault-reaction code.
"""

from __future__ import annotations

import logging

from drivers.cia402 import (
    FAULT_REACTION_OPTIONS,
    HALT_OPTIONS,
    HEARTBEAT_LOST,
    MODES,
    PROFILE_POSITION,
    PROFILE_VELOCITY,
    QUICK_STOP_OPTIONS,
    SLOW_DOWN_OPTIONS,
    AbortReaction,
    Cw,
    DriveErrorCode,
    Od,
    Ramp,
    State,
    Sw,
    decode_command,
    describe_error,
    transition,
)
from sims.drive_motion import DriveMotion

log = logging.getLogger("sims.drive_twin")


class DriveStateMachine(DriveMotion):
    """The drive's CiA 402 state, fault and error register, and the reactions that
    change them."""

    _fault: DriveErrorCode | None
    _error_register: int
    _velocity_units: int
    _position_counts: int
    emcy_sent: list[tuple[float, int]]

    def _init_state_machine(self) -> None:
        """Power-on: Not ready to switch on, no mode, no fault."""
        self._state = State.NOT_READY_TO_SWITCH_ON
        self._mode = 0
        self._controlword = 0
        self._fault = None
        self._error_register = 0
        self._after_standstill = None
        self._velocity_units = 0
        self._position_counts = 0
        self.emcy_sent = []  # (stand time, code)
        #: mode code -> what entering Operation enabled or a new set-point does in it
        self._mode_handlers = {PROFILE_VELOCITY.code: self._pv_follow_target,
                               PROFILE_POSITION.code: self._pp_hold}

    @property
    def state(self) -> State:
        with self._lock:
            return self._state

    @property
    def fault(self) -> DriveErrorCode | None:
        with self._lock:
            return self._fault

    def inject(self, fault: DriveErrorCode | int) -> None:
        """An internal fault: EMCY, then the fault reaction (0x605E) and the Fault state."""
        if isinstance(fault, int):
            fault = DriveErrorCode(fault, describe_error(fault))
        with self._lock:
            self._raise_fault(fault)

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

    def _on_controlword(self, cw: int) -> None:
        previous = self._controlword
        self._state_machine(cw)
        if self._state is State.OPERATION_ENABLED and self._after_standstill is None \
                and (cw ^ previous) & Cw.HALT:
            self._halt_changed()


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
