"""What the axis's drive reports (drivers/axis.py): the TPDOs' velocity and position
actual values and statusword, stamped on arrival with the bench clock, the drive's
heartbeats and EMCYs (heard in canopen's receive thread), the rate and position read
back from them, and the waits on them: standstill, and the rate settled.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from canopen.emcy import EmcyError
    from canopen.pdo.base import PdoMap

from drivers.axis_errors import AxisError, AxisTimeout
from drivers.axis_link import REAL_MARGIN_S, STANDSTILL_DPS, STEPPED_POLL_S, AxisLink
from drivers.cia402 import DriveUnits, Mode, Od, State, decode_state, describe_error, unwrap_int32
from drivers.clock import can_channel_name, consumed, real_budget_s, stepped
from drivers.settle import RippleJudgement, hold_spans_turns, judge_with_ripple
from drivers.waits import Deadline


@dataclass(frozen=True)
class Feedback:
    """One TPDO's worth of drive readings, stamped on arrival with the bench clock."""

    t_s: float
    velocity_dps: float
    position_deg: float
    statusword: int



class AxisReadback(AxisLink):
    """The drive's feedback as the controller hears it, and the waits on it."""

    units: DriveUnits
    mode: Mode
    feedback_journal_s: float
    max_rate_dps: float

    def _init_readback(self) -> None:
        """Nothing heard from the drive yet."""
        self._feedback_journaled_t: float | None = None
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
        self._target_dps = 0.0

    @property
    def state(self) -> State | None:
        """The 402 state of the latest statusword received."""
        with self._lock:
            return self._state

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
            new, seq, target = self._settle_readings(seq)
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
                judged = self._judge_ripple(window, new, hold_s, target, tolerance_dps)
                if judged is not None and judged.settled:
                    return self._settled_with_ripple(judged, window, target, tolerance_dps)
                held_s = _ripple_held_s(window, judged)
            elif len(run) >= 2:
                held_s = run[-1].t_s - run[0].t_s
            if on_hold is not None and new:
                on_hold(held_s)
            if not ripple_rule and len(run) >= 2 and run[-1].t_s - run[0].t_s >= hold_s:
                return self._settled_every_reading(run, target, tolerance_dps)
            if timed_out or deadline.expired():
                raise self._not_settled(tolerance_dps, target, hold_s, timeout_s, last_v,
                                        judged)
            if stepped(self.clock):  # co-simulation: the next readings are stand time away
                if self.clock.now() > t_end:
                    timed_out = True
                    continue
                self.clock.sleep(max(self._tpdo_period_s, STEPPED_POLL_S))
                continue
            with self._lock:
                self._lock.wait(timeout=0.05)

    def _settle_readings(self, seq: int) -> tuple[list[Feedback], int, float]:
        """The readings received since frame `seq`, the frame count now and the rate
        target, once `check()` found no fault; refused if the drive left Operation
        enabled (a settle would wait on a table the drive no longer holds)."""
        self.check()
        with self._lock:
            new = list(self._samples)[-(self._seq - seq):] if self._seq > seq else []
            seq = self._seq
            target = self._target_dps
            state = self._state
        if state is not State.OPERATION_ENABLED:
            raise AxisError(f"axis {self.name}: the drive left operation enabled while "
                            f"settling (it shows {state.label if state else '?'})")
        return new, seq, target

    @staticmethod
    def _judge_ripple(window: deque[Feedback], new: list[Feedback], hold_s: float,
                      target: float, tolerance_dps: float) -> RippleJudgement | None:
        """The readings of the last `hold_s` (the window, with `new` added), judged with
        the turn's ripple set aside; None while they do not span `hold_s` yet."""
        window.extend(new)
        while len(window) >= 2 and window[-1].t_s - window[1].t_s >= hold_s:
            window.popleft()
        if len(window) >= 2 and window[-1].t_s - window[0].t_s >= hold_s:
            return judge_with_ripple([f.t_s for f in window],
                                     [f.velocity_dps for f in window],
                                     [f.position_deg for f in window],
                                     target, tolerance_dps)
        return None

    def _settled_with_ripple(self, judged: RippleJudgement, window: deque[Feedback],
                             target: float, tolerance_dps: float) -> float:
        self._journal("settled", target_dps=target, mean_dps=judged.mean_dps,
                      samples=len(window), hold_s=window[-1].t_s - window[0].t_s,
                      tolerance_dps=tolerance_dps, rule="ripple set aside",
                      ripple_peak_dps=judged.ripple_peak_dps,
                      ripple_orders=judged.orders, turns=judged.turns,
                      worst_residual_dps=judged.worst_residual_dps)
        self.last_settle = judged
        return judged.mean_dps

    def _settled_every_reading(self, run: list[Feedback], target: float,
                               tolerance_dps: float) -> float:
        mean = math.fsum(f.velocity_dps for f in run) / len(run)
        self._journal("settled", target_dps=target, mean_dps=mean, samples=len(run),
                      hold_s=run[-1].t_s - run[0].t_s, tolerance_dps=tolerance_dps,
                      rule="every reading")
        self.last_settle = None
        return mean

    def _not_settled(self, tolerance_dps: float, target: float, hold_s: float,
                     timeout_s: float, last_v: float | None,
                     judged: RippleJudgement | None) -> AxisTimeout:
        ripple = (f"; with the turn's ripple ({judged.ripple_peak_dps:.3g} deg/s peak) "
                  f"set aside the rest still reached {judged.worst_residual_dps:.3g} "
                  "deg/s" if judged is not None else "")
        return AxisTimeout(f"axis {self.name}: the rate did not settle within "
                           f"{tolerance_dps:g} deg/s of {target:g} deg/s for {hold_s:g} s "
                           f"in {timeout_s:g} s (last velocity actual: "
                           f"{'none' if last_v is None else f'{last_v:.6g} deg/s'}"
                           f"{ripple})")

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


def _ripple_held_s(window: deque[Feedback], judged: RippleJudgement | None) -> float:
    """How long the readings have held, ripple set aside: since the last one out of
    tolerance, else the whole window."""
    if judged is not None and judged.last_out is not None:
        return window[-1].t_s - list(window)[judged.last_out].t_s
    if window:
        return window[-1].t_s - window[0].t_s
    return 0.0
