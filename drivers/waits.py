"""Real-time limits for every wait on an instrument, in sim and on hardware.

A wait is given in the clock's seconds (the stand's time); its limit in real seconds is
that time divided by the clock's speed plus a margin, and the margin is never shorter
than `MIN_REAL_MARGIN_S`. On a loaded host (two busy processes on two cores) a thread can
be starved for a second or more, and a twin producing 100 000 FOG frames a real second
falls behind its clock: 10 s of stand time at 100x is 0.1 s real, far less than such a
hiccup. A slow machine must slow the run, not abort it.

On a stepped clock (a co-simulation, drivers/clock.py) a wait for an instrument is a
wait on the clock: `wait_on_clock` lets clock time pass in steps until the instrument is
ready, and its limit is clock time, so when a wait ends depends on the data alone.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from drivers.clock import Clock, stepped

#: the shortest real-time margin any wait gets beyond its scaled clock time (seconds)
MIN_REAL_MARGIN_S = 5.0
#: how far past its limit a wait may go while data still arrive late (a slow host); a
#: stream that stays further behind than this is a fault, not a slow machine
MAX_LATE_REAL_S = 60.0


#: a poll that comes back this much (real s) after the one before means the host did not
#: run this thread meanwhile (a loaded machine, a stopped process, a paused VM)
HOST_STALL_S = 1.0


class Deadline:
    """A real-time limit for a polling wait that does not count time the host did not run
    the waiting thread.

    While the host does not run this process, nor do the threads that deliver what the
    wait is for (a CAN notifier, a serial reader, a twin), so the limit moves out by every
    gap between two polls longer than `HOST_STALL_S`: a starved host slows a wait and
    does not fail it (CI beside two busy processes: a drive's standstill "timed out after
    6.55 s" across a 7 s stall of the whole process). On hardware the same holds: the
    instrument kept its time; we were the ones away. Poll at least every few ms.
    """

    def __init__(self, seconds: float) -> None:
        now = time.monotonic()
        self._end = now + seconds
        self._last = now
        #: real seconds of host stalls forgiven so far
        self.stalled_s = 0.0

    def expired(self) -> bool:
        now = time.monotonic()
        gap = now - self._last
        self._last = now
        if gap > HOST_STALL_S:
            self._end += gap
            self.stalled_s += gap
        return now > self._end


def real_limit_s(clock_s: float, speed: float, margin_s: float = MIN_REAL_MARGIN_S) -> float:
    """Real seconds allowed for a wait of `clock_s` on a clock running `speed` x real time."""
    return max(clock_s, 0.0) / speed + max(margin_s, MIN_REAL_MARGIN_S)


#: real seconds between looks while a stepped clock stands still (paused: nothing runs)
_PAUSED_POLL_REAL_S = 0.005


def wait_on_clock(clock: Clock, ready: Callable[[], bool], timeout_s: float,
                  step_s: float | Callable[[], float]) -> bool:
    """On a stepped clock: let up to `timeout_s` of clock time pass, `step_s` at a time
    (a number, or a function saying how far to the next look), until `ready()`.

    Returns whether it became ready. If the clock stands still (paused), the wait falls
    back on real time with the same limit, so it ends either way.
    """
    t_end = clock.now() + timeout_s
    real_end = time.monotonic() + timeout_s + MIN_REAL_MARGIN_S
    while not ready():
        t = clock.now()
        if t >= t_end:
            return False
        step = step_s() if callable(step_s) else step_s
        clock.sleep(min(max(step, 1e-6), t_end - t))
        if clock.now() <= t:  # a paused clock: nothing will change by clock time
            if time.monotonic() > real_end:
                return bool(ready())
            time.sleep(_PAUSED_POLL_REAL_S)
    return True


def poll_time(clock: Clock) -> tuple[Callable[[], float], Callable[[float], None]]:
    """(now, sleep) for a driver's polls: on a stepped clock the clock's own, so polling
    lets clock time pass and a poll's time is fixed by the data; else real seconds."""
    if stepped(clock):
        return clock.now, clock.sleep
    return time.monotonic, time.sleep
