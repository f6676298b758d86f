"""The bench's clock: every wait in the engine goes through one of these.

On a real bench the clock is the host's monotonic clock. On the simulated bench it is
the simulated stand's virtual clock (sims.clock.VirtualClock), which runs faster than
real time; the engine's code is the same for both.

It lives with the drivers because they are the bottom layer: every driver waits and
timestamps through it, and nothing here may import from above (bench, sims, procedures).
"""

from __future__ import annotations

import time
from typing import Protocol


class Clock(Protocol):
    """What the engine and the drivers need of a clock (seconds)."""

    speed: float

    def now(self) -> float: ...

    def sleep(self, duration_s: float) -> None: ...


class MonotonicClock:
    """Real seconds since construction."""

    speed: float = 1.0
    min_speed: float = 1.0

    def __init__(self) -> None:
        self._t0 = time.monotonic()

    def now(self) -> float:
        return time.monotonic() - self._t0

    def sleep(self, duration_s: float) -> None:
        if duration_s > 0:
            time.sleep(duration_s)


def min_speed(clock: Clock) -> float:
    """The slowest `clock` can run, virtual seconds per real one.

    Real-time budgets that detect a failure (an instrument that never answers) divide a
    span of bench time by this, not by `speed`: a paced simulated clock slows down when a
    twin lags (sims.clock), and a wait budgeted at its top speed would call a slow machine
    a dead instrument.
    """
    return float(getattr(clock, "min_speed", clock.speed))


def real_budget_s(clock: Clock, bench_s: float) -> float:
    """The longest `bench_s` seconds of bench time can take in real time."""
    return bench_s / min_speed(clock)
