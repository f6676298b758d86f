"""The bench's clock: every wait in the engine goes through one of these.

On a real bench the clock is the host's monotonic clock. On the simulated bench it is
the simulated stand's virtual clock (sims.clock.VirtualClock), which runs faster than
real time; the engine's code is the same for both.

A clock may be `stepped` (sims.clock.SteppedClock, the co-simulation of the twins): its
time passes only while a thread waits on it, and only once every twin and every reader
has finished with the instant before. Drivers then wait for an instrument by waiting on
the clock (drivers/waits.py), and tell it what they consumed of each channel
(`channel_opened`, `consumed`, `channel_closed`: a pty's bytes, a CAN node's TPDOs), so
the clock knows when a channel is drained. On any other clock (hardware's) these calls
do nothing and waits are in real time.

It lives with the drivers because they are the bottom layer: every driver waits and
timestamps through it, and nothing here may import from above (bench, sims, procedures).
"""

from __future__ import annotations

import time
from typing import Protocol


class Clock(Protocol):
    """What the engine and the drivers need of a clock (seconds)."""

    @property
    def speed(self) -> float: ...   # read only: a sim's clock measures its own

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


def stepped(clock: Clock) -> bool:
    """True when `clock`'s time passes only in waits on it (a co-simulation)."""
    return bool(getattr(clock, "stepped", False))


def channel_opened(clock: Clock, name: str) -> None:
    """A driver reads channel `name` from now on (a stepped clock counts it)."""
    hook = getattr(clock, "channel_opened", None)
    if hook is not None:
        hook(name)


def consumed(clock: Clock, name: str, n: int) -> None:
    """A driver has consumed `n` units of channel `name` (bytes, messages)."""
    hook = getattr(clock, "consumed", None)
    if hook is not None:
        hook(name, n)


def in_flight(clock: Clock, name: str) -> int:
    """Units a stepped clock's twin has sent on channel `name` that its driver has not
    reported consumed yet (0 on any other clock: a real instrument announces nothing).
    A driver may wait for them (they are on their way), never count on them."""
    hook = getattr(clock, "backlog", None)
    return int(hook(name)) if hook is not None else 0


def settle_channel(clock: Clock, name: str) -> None:
    """About to read channel `name`: a stepped clock first has its twin deliver what
    [0, now] holds (sims/clock.py `settle_channel`); nothing on any other clock."""
    hook = getattr(clock, "settle_channel", None)
    if hook is not None:
        hook(name)


def channel_closed(clock: Clock, name: str) -> None:
    hook = getattr(clock, "channel_closed", None)
    if hook is not None:
        hook(name)


def can_channel_name(channel: str, node_id: int) -> str:
    """A CAN node's TPDOs as one channel of a stepped clock (driver and twin agree)."""
    return f"can:{channel}:{node_id}"
