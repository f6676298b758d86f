"""The simulated stand's virtual clock: the only clock any twin reads.

Virtual seconds run up to `top_speed` times faster than real ones, so a ladder that would
take hours on a real table takes minutes. Twins never keep a clock of their own; they ask
this one, so the counter's zero marks, the FOG's samples and the drive's ramp all live on
one time axis.

Pacing. A twin that streams (the FOG) registers a pacer: a function saying up to which
virtual time it has delivered its data. The clock then never runs more than `lead_s`
ahead of the slowest pacer, so a twin that cannot keep up (a loaded machine, a slow
reader) slows the clock instead of leaving its reader waiting for data "that should
have arrived". With `top_speed = inf` (`sim: clock_speed: max`) the twins alone set the
pace: the stand runs as fast as every twin keeps up. A fixed speed stays available: it
is a cap, and without pacers the clock runs exactly at it. Whatever the pacers say, the
clock never runs slower than `floor_speed` (real time by default: a real bench's pace),
so a twin that died cannot freeze the run, and `min_speed` is a speed every real-time
budget for failure detection can rely on. Pacing twins that nobody reads (the bench is
closing) hold the clock at that floor: nothing is measured, and the drive twins' CAN
threads are not made to generate hours of stand samples while they answer the stop.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable

#: `sim: clock_speed: max`
MAX = "max"
#: virtual seconds a paced clock may run ahead of the slowest twin's delivered data
DEFAULT_LEAD_S = 20.0
#: the paced clock never runs slower than real time (the pace of a real bench)
REAL_TIME = 1.0
#: "max" on a stand with no twin that paces (nothing streams): a finite top speed all the same
UNPACED_MAX_SPEED = 500.0
_SPEED_WINDOW_REAL_S = 0.5   # real seconds over which the running speed is measured
_POLL_MAX_REAL_S = 0.02      # a paced sleep looks at the clock at least this often
_POLL_MIN_REAL_S = 0.0005

#: a pacer: the virtual time (s) up to which a twin has delivered its output
Pacer = Callable[[], float]


def parse_speed(value: float | str | None, default: float | str = MAX) -> float:
    """`sim: clock_speed` as a top speed: a number > 0, or "max" (inf)."""
    v = default if value is None else value
    if isinstance(v, str):
        if v.strip().lower() == MAX:
            return math.inf
        raise ValueError(f"clock speed must be a number > 0 or {MAX!r}, got {v!r}")
    speed = float(v)
    if not speed > 0:
        raise ValueError(f"clock speed must be > 0, got {v}")
    return speed


class VirtualClock:
    """Virtual time, advanced at `top_speed` in real time unless a pacer holds it back."""

    def __init__(self, speed: float | str = 1.0, start_s: float = 0.0, running: bool = True,
                 *, lead_s: float = DEFAULT_LEAD_S, floor_speed: float = REAL_TIME) -> None:
        self.top_speed = parse_speed(speed)
        if not lead_s > 0:
            raise ValueError(f"clock lead must be > 0, got {lead_s}")
        self.lead_s = float(lead_s)
        self.floor_speed = min(float(floor_speed), self.top_speed)
        self._lock = threading.Lock()
        self._t_s = float(start_s)
        self._m_last: float | None = time.monotonic() if running else None
        self._pacers: list[Pacer] = []
        top = self.top_speed if math.isfinite(self.top_speed) else UNPACED_MAX_SPEED
        self._measured = (self._m_last, self._t_s, top)  # (real, virtual, speed) of the window

    # -- speeds -------------------------------------------------------------------------
    @property
    def speed(self) -> float:
        """Virtual seconds per real second, as the clock runs now (for estimates).

        A fixed-speed clock without pacers runs exactly at its speed; a paced one reports
        its measured pace over the last half second of real time.
        """
        if not self._pacers and math.isfinite(self.top_speed):
            return self.top_speed
        return self._measured[2]

    @property
    def min_speed(self) -> float:
        """The slowest this clock can run: real-time budgets for failures divide by it."""
        return self.floor_speed if self._pacers else self.speed

    @property
    def paced(self) -> bool:
        return bool(self._pacers)

    def pace(self, pacer: Pacer) -> Callable[[], None]:
        """Hold the clock within `lead_s` of what `pacer` has delivered; returns the undo."""
        with self._lock:
            self._advance_locked()
            self._pacers.append(pacer)

        def unpace() -> None:
            with self._lock:
                self._advance_locked()
                if pacer in self._pacers:
                    self._pacers.remove(pacer)
        return unpace

    # -- time ---------------------------------------------------------------------------
    def start(self) -> None:
        """Let a paused clock run: the simulated bench starts every twin first, then this."""
        with self._lock:
            if self._m_last is None:
                self._m_last = time.monotonic()
                self._measured = (self._m_last, self._t_s, self._measured[2])

    def pause(self) -> None:
        """Stop the clock where it is (the simulated bench stopped: no twin runs)."""
        with self._lock:
            self._advance_locked()
            self._m_last = None

    @property
    def running(self) -> bool:
        return self._m_last is not None

    def now(self) -> float:
        with self._lock:
            return self._advance_locked()

    def _advance_locked(self) -> float:
        if self._m_last is None:
            return self._t_s
        m = time.monotonic()
        dt_real = m - self._m_last
        self._m_last = m
        free = self._t_s + self.top_speed * dt_real if dt_real > 0 else self._t_s
        if not math.isfinite(free):
            free = self._t_s + UNPACED_MAX_SPEED * dt_real
        limit = min((p() for p in self._pacers), default=math.inf) + self.lead_s
        if math.isfinite(limit):  # a twin streams: stay within lead_s of its data
            t_new = max(self._t_s + self.floor_speed * dt_real, min(free, limit))
        elif self._pacers:  # twins that pace, but nobody reads them (closing): no hurry
            t_new = self._t_s + self.floor_speed * dt_real
        else:
            t_new = free
        self._t_s = max(self._t_s, t_new)
        m0, t0, speed = self._measured
        if m0 is not None and m - m0 >= _SPEED_WINDOW_REAL_S:
            self._measured = (m, self._t_s, max((self._t_s - t0) / (m - m0), self.floor_speed))
        return self._t_s

    def sleep(self, duration_s: float) -> None:
        """Sleep `duration_s` virtual seconds."""
        if duration_s <= 0:
            return
        if (not self._pacers and math.isfinite(self.top_speed)) or not self.running:
            time.sleep(duration_s / self.speed)
            return
        self.sleep_until(self.now() + duration_s)

    def sleep_until(self, t_s: float) -> None:
        if (not self._pacers and math.isfinite(self.top_speed)) or not self.running:
            self.sleep(t_s - self.now())
            return
        while (left := t_s - self.now()) > 0:
            time.sleep(min(max(left / self.speed, _POLL_MIN_REAL_S), _POLL_MAX_REAL_S))

    def real_seconds(self, virtual_s: float) -> float:
        """The longest a virtual interval can take in real time (for real-time timeouts)."""
        return virtual_s / self.min_speed
