"""The drive twin's motion: its profile generators (CiA 402 profile velocity and profile
position) turning the stand model's axis, the ramps its stops take, and the statusword
bits that follow from the motion (speed zero, target reached).

The profile generator is the stand model's own ramp (`AxisModel.command_rate`), so the
FOG and counter twins see exactly the motion the drive commands. Everything here runs
on the stand's clock, with the motion lock held.
"""

from __future__ import annotations

from collections.abc import Callable

from drivers.cia402 import PROFILE_POSITION, PROFILE_VELOCITY, Cw, Od, Ramp, State, wrap_int32
from sims.drive_objects import DriveObjects

#: profile position: how many times the twin's position loop re-aims after a move
PP_MAX_CORRECTIONS = 5


class DriveMotion(DriveObjects):
    """What the table does when the drive commands it, in the drive's objects' units."""

    #: the CiA 402 state machine's (sims/drive_state_machine.py), read here
    _mode: int
    _controlword: int
    _after_standstill: State | None
    #: mode code -> what entering Operation enabled or a new set-point does in it
    _mode_handlers: dict[int, Callable[..., None]]
    coast_decel_dps2: float
    _speed_zero_since: float | None
    _in_window_since: float | None
    _speed_zero: bool
    _target_reached: bool
    _set_point_ack: bool
    _pp_target_deg: float | None
    _pp_corrections: int
    _in_position_since: float | None

    def _init_motion(self) -> None:
        """At power-on the axis stands: speed zero, no set-point."""
        self._speed_zero_since = 0.0
        self._in_window_since = None
        self._speed_zero = True
        self._target_reached = False
        self._set_point_ack = False           # PP: statusword bit 12
        self._pp_target_deg = None
        self._pp_corrections = 0
        self._in_position_since = None

    @property
    def _halted(self) -> bool:
        return bool(self._controlword & Cw.HALT)

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

    def _update_motion_bits(self, t: float, w: float) -> None:
        """Statusword bits 12 (speed 0) and 10 (target reached), on stand time (CiA 402 PV)."""
        if abs(w) <= self._threshold_dps():
            self._speed_zero_since, self._speed_zero = _held(
                self._speed_zero_since, t, self._get(Od.VELOCITY_THRESHOLD_TIME))
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
                self._in_window_since, self._target_reached = _held(
                    self._in_window_since, t, self._get(Od.VELOCITY_WINDOW_TIME))
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
                self._in_position_since, self._target_reached = _held(
                    self._in_position_since, t, self._get(Od.POSITION_WINDOW_TIME))
            else:
                self._in_position_since = None
                self._target_reached = False
        else:
            self._in_window_since = None
            self._target_reached = self._state is State.QUICK_STOP_ACTIVE and self._speed_zero


def _held(since_s: float | None, t_s: float, hold_ms: int) -> tuple[float, bool]:
    """A statusword condition true now, since `since_s` (None: since t_s): when it began,
    and whether it has held the time its object gives (0x6070, 0x606E, 0x6068, in ms)."""
    since_s = t_s if since_s is None else since_s
    return since_s, t_s - since_s >= hold_ms / 1000.0
