"""The simulated stand's virtual clock: the only clock any twin reads.

Virtual seconds run `speed` times faster than real ones, so a ladder that would take
hours on a real table takes seconds. Twins never keep a clock of their own; they ask
this one, so the counter's zero marks, the FOG's samples and the drive's ramp all
live on one time axis.
"""

from __future__ import annotations

import threading
import time


class VirtualClock:
    """Virtual time = speed * real time elapsed since start (plus any skips)."""

    def __init__(self, speed: float = 1.0, start_s: float = 0.0, running: bool = True) -> None:
        if speed <= 0:
            raise ValueError(f"clock speed must be > 0, got {speed}")
        self.speed = float(speed)
        self._lock = threading.Lock()
        self._offset_s = float(start_s)
        self._m0: float | None = time.monotonic() if running else None

    def start(self) -> None:
        """Let a paused clock run: the simulated bench starts every twin first, then this."""
        with self._lock:
            if self._m0 is None:
                self._m0 = time.monotonic()

    @property
    def running(self) -> bool:
        return self._m0 is not None

    def now(self) -> float:
        with self._lock:
            if self._m0 is None:
                return self._offset_s
            return self._offset_s + self.speed * (time.monotonic() - self._m0)

    def sleep(self, duration_s: float) -> None:
        """Sleep `duration_s` virtual seconds (duration_s / speed real ones)."""
        if duration_s > 0:
            time.sleep(duration_s / self.speed)

    def sleep_until(self, t_s: float) -> None:
        self.sleep(t_s - self.now())

    def real_seconds(self, virtual_s: float) -> float:
        """How long a virtual interval takes in real time (for real-time timeouts)."""
        return virtual_s / self.speed
