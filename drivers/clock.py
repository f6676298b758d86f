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

    def __init__(self) -> None:
        self._t0 = time.monotonic()

    def now(self) -> float:
        return time.monotonic() - self._t0

    def sleep(self, duration_s: float) -> None:
        if duration_s > 0:
            time.sleep(duration_s)
