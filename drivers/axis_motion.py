"""The axis driver's motion commands (drivers/axis.py): a rate in profile velocity, a
stop, a quick stop, disabling, and a turn to an angle in profile position, each checked
against the stand's rate and acceleration limits before anything is sent (nothing is
ever clipped).
"""

from __future__ import annotations

import math

from drivers.axis_errors import AxisError, LimitError, PositionError
from drivers.axis_link import REAL_MARGIN_S, STANDSTILL_DPS, STATE_TIMEOUT_S
from drivers.axis_states import AxisStateMachine
from drivers.cia402 import (
    PROFILE_POSITION,
    PROFILE_VELOCITY,
    Command,
    Cw,
    Od,
    State,
    Sw,
    wrap_int32,
)
from drivers.clock import real_budget_s


class AxisMotion(AxisStateMachine):
    """What the axis is told to do, within the stand's limits."""

    position_tolerance_deg: float

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
