"""Real-time limits for every wait on an instrument, in sim and on hardware.

A wait is given in the clock's seconds (the stand's time); its limit in real seconds is
that time divided by the clock's speed plus a margin, and the margin is never shorter
than `MIN_REAL_MARGIN_S`. On a loaded host (two busy processes on two cores) a thread can
be starved for a second or more, and a twin producing 100 000 FOG frames a real second
falls behind its clock: 10 s of stand time at 100x is 0.1 s real, far less than such a
hiccup. A slow machine must slow the run, not abort it.
"""

from __future__ import annotations

#: the shortest real-time margin any wait gets beyond its scaled clock time (seconds)
MIN_REAL_MARGIN_S = 5.0
#: how far past its limit a wait may go while data still arrive late (a slow host); a
#: stream that stays further behind than this is a fault, not a slow machine
MAX_LATE_REAL_S = 60.0


def real_limit_s(clock_s: float, speed: float, margin_s: float = MIN_REAL_MARGIN_S) -> float:
    """Real seconds allowed for a wait of `clock_s` on a clock running `speed` x real time."""
    return max(clock_s, 0.0) / speed + max(margin_s, MIN_REAL_MARGIN_S)
