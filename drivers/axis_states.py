"""The axis driver's CiA 402 client state machine (drivers/axis.py): the drive brought
to Operation enabled (fault reset, mode, a zero set-point first), the modes of
operation selected and checked, and the controlword paths between states that the
drive's quick-stop option code allows (drivers/cia402.py path).
"""

from __future__ import annotations

import time

from drivers.axis_errors import AxisError, AxisTimeout
from drivers.axis_link import STATE_TIMEOUT_S, STEPPED_POLL_S
from drivers.axis_readback import AxisReadback
from drivers.cia402 import (
    PROFILE_VELOCITY,
    QUICK_STOP_STAYS,
    Cw,
    Mode,
    Od,
    State,
    decode_state,
    describe_error,
    path,
    transition,
)
from drivers.clock import stepped
from drivers.waits import Deadline


class AxisStateMachine(AxisReadback):
    """The drive's 402 state as the controller commands it."""

    quick_stop_option: int | None
    accel_dps2: float
    max_accel_dps2: float
    _quick_stop_decel_dps2: float
    _accel_sent: int | None
    _decel_dps2: float

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


    def _send_accel(self, accel_dps2: float) -> None:
        """0x6083/0x6084, the ramps the drive takes to every set-point (and enables onto),
        within the stand's limit; written only when they change."""
        units = self.units.dps2_to_accel(accel_dps2, limit_dps2=self.max_accel_dps2)
        if units != self._accel_sent:
            self._write(Od.PROFILE_ACCELERATION, units)
            self._write(Od.PROFILE_DECELERATION, units)
            self._accel_sent = units
            self._decel_dps2 = self.units.accel_to_dps2(units)
