"""Where the run is in its plan, and how long it has left, in bench time and in wall time.

Bench time left comes from the plan's step estimates (the time the table needs). Wall time
left is measured, never assumed: the simulated clock may run at a fixed multiple of real
time or as fast as the twins keep up (`clock_speed: max`), and every step also costs wall
time that the plan does not count (analysing a pair, opening a file). So each finished
step's wall time is fitted as `wall = a * estimate + b` (a: wall seconds per bench
second, the inverse of the measured speed; b: the fixed cost of a step), and the steps
still to do are predicted with the same line. Work that runs beside the steps (a pair's
first look in the analysis worker) is waited for at the end: its measured backlog is a
floor under the estimate.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from bench.core.plan import format_duration

MIN_TIMED_FRACTION = 0.01


def format_eta(seconds: float | None) -> str:
    """A time left as a person reads it: minutes and seconds, tenths below ten seconds.

    Tenths, because a fast simulated run has its last minute of bench time in a fraction
    of a wall second, and '0 s' while work remains reads as 'done'.
    """
    if seconds is None or not math.isfinite(seconds):
        return "measuring"
    seconds = max(seconds, 0.0)
    if 0 < seconds < 0.05:
        return "< 0.1 s"
    if seconds >= 59.5:
        return format_duration(seconds)
    if seconds >= 9.95:
        return f"{seconds:.0f} s"
    return f"{seconds:.1f} s"


@dataclass(frozen=True)
class Eta:
    """One reading of the timeline, for every console to print the same way."""

    index: int                 # the current step, 0-based (-1 before the first)
    steps: int
    done_fraction: float       # of the plan's bench time, 0..1
    step_fraction: float       # of the current step's estimate, 0..1 (0 without one)
    bench_left_s: float
    wall_left_s: float | None  # None until a step with bench time has been timed
    speed: float | None        # measured bench seconds per wall second so far

    def bench_text(self) -> str:
        return format_eta(self.bench_left_s)

    def wall_text(self) -> str:
        return format_eta(self.wall_left_s)

    def speed_text(self) -> str:
        if self.speed is None:
            return "speed not yet measured"
        return f"{self.speed:.3g}× real time, measured"


def fit_step_cost(estimates_s: Sequence[float], walls_s: Sequence[float]
                  ) -> tuple[float, float] | None:
    """(a, b) of wall = a * estimate + b over the timed steps, both >= 0; None if nothing
    can be fitted. Least squares, falling back to one term when the other comes out
    negative (a fast first step must not predict negative wall time)."""
    pts = [(e, w) for e, w in zip(estimates_s, walls_s, strict=True) if w >= 0]
    if not pts:
        return None
    n = len(pts)
    se = sum(e for e, _ in pts)
    sw = sum(w for _, w in pts)
    see = sum(e * e for e, _ in pts)
    sew = sum(e * w for e, w in pts)
    det = n * see - se * se
    if det > 1e-12 * max(see * n, 1.0):
        a = (n * sew - se * sw) / det
        b = (sw - a * se) / n
        if a >= 0 and b >= 0:
            return a, b
    a_only = sew / see if see > 0 else 0.0                    # wall = a * estimate
    b_only = sw / n                                           # wall = b
    r_a = sum((w - a_only * e) ** 2 for e, w in pts)
    r_b = sum((w - b_only) ** 2 for _, w in pts)
    return (a_only, 0.0) if see > 0 and r_a <= r_b else (0.0, b_only)


class Timeline:
    """The plan's steps against the clock: fed by the engine, read by the consoles."""

    def __init__(self, estimates_s: Sequence[float], clock_now: Callable[[], float],
                 wall_now: Callable[[], float] = time.monotonic,
                 backlog_s: Callable[[], float] | None = None) -> None:
        self.estimates_s = [max(float(e), 0.0) for e in estimates_s]
        self.total_s = sum(self.estimates_s)
        self._clock_now = clock_now
        self._wall_now = wall_now
        self._backlog_s = backlog_s or (lambda: 0.0)
        self.index = -1
        self._walls: list[float] = []
        self._timed: list[float] = []
        self._step_wall0 = wall_now()
        self._step_bench0 = clock_now()
        self._wall0 = self._step_wall0
        self._bench0 = self._step_bench0

    def start(self, index: int) -> None:
        self.index = index
        self._step_wall0 = self._wall_now()
        self._step_bench0 = self._clock_now()

    def finish(self, index: int) -> None:
        self._timed.append(self.estimates_s[index])
        self._walls.append(self._wall_now() - self._step_wall0)

    def now(self) -> Eta:
        i = self.index
        n = len(self.estimates_s)
        if i < 0:
            return Eta(i, n, 0.0, 0.0, self.total_s, None, None)
        est = self.estimates_s
        in_step_bench = max(self._clock_now() - self._step_bench0, 0.0)
        current_left = max(est[i] - in_step_bench, 0.0)
        later = sum(est[i + 1:])
        bench_left = current_left + later
        done = 1.0 - bench_left / self.total_s if self.total_s > 0 else i / max(n, 1)
        wall_left: float | None = None
        # a line fitted to a few short steps says little about hours of turning: wait for
        # steps that together make at least MIN_TIMED_FRACTION of the plan's bench time
        timed_enough = sum(self._timed) >= MIN_TIMED_FRACTION * self.total_s and any(self._timed)
        fit = fit_step_cost(self._timed, self._walls) if timed_enough else None
        if fit is not None:
            a, b = fit
            in_step_wall = self._wall_now() - self._step_wall0
            current = max(a * est[i] + b - in_step_wall, 0.0)
            # work beside the steps (the worker's analyses) runs meanwhile; the end waits
            # for whichever finishes last
            wall_left = max(current + a * later + b * (n - i - 1), self._backlog_s())
        wall_run = self._wall_now() - self._wall0
        bench_run = self._clock_now() - self._bench0
        speed = bench_run / wall_run if wall_run > 0.5 and bench_run > 0 else None
        step_fraction = min(in_step_bench / est[i], 1.0) if est[i] > 0 else 0.0
        return Eta(i, n, min(max(done, 0.0), 1.0), step_fraction, bench_left, wall_left,
                   speed)
