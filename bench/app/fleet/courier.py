"""The background delivery of a running run to the lab database.

A thread of the bench process reads what the run has journaled and delivers it every
`PERIOD_S`, with a health sample (health.py). It only reads the run directory, so it never
changes what the run measures, and it never raises into the run: the lab database being
unreachable is a warning and a `lab_link` event in the run's own log (down, then up
again), and what was not delivered stays in the run directory until the next delivery
(this courier's, the run's last one, or `bench records sync`).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path

from bench.app.fleet.health import sample
from bench.app.fleet.outbox import Outbox
from bench.app.fleet.sync import Intervals, LabLink, SyncError
from bench.core import events as ev
from bench.core.journal import RunDir

PERIOD_S = 0.5            # the station's update latency budget is 2 s (issue 44)
Warn = Callable[[str], None]


class Courier:
    """Delivers one running run while it runs (`start`), and once more at its end
    (`finish`, which also registers the result)."""

    def __init__(self, run: RunDir, url: str, bench: str, warn: Warn,
                 period_s: float = PERIOD_S, interval_for: Intervals | None = None) -> None:
        self.run, self.bench, self.warn, self.period_s = run, bench, warn, period_s
        self.path: Path = run.path
        self.link = LabLink(url, interval_for)
        self.outbox = Outbox(run.path.parent, url)
        self.down: str | None = None          # the reason while the lab is unreachable
        self._stop = threading.Event()
        self._lock = threading.Lock()         # one delivery at a time (thread and finish)
        self._thread = threading.Thread(target=self._loop, name="lab-courier", daemon=True)

    def start(self) -> Courier:
        self._thread.start()
        return self

    def _loop(self) -> None:
        while not self._stop.wait(self.period_s):
            self.deliver(register=False)

    def deliver(self, register: bool) -> bool:
        """One delivery; False when the lab database could not take it."""
        with self._lock:
            try:
                self.link.deliver(self.path, self.outbox, self.bench, sample(self.path),
                                  register=register)
            except SyncError as e:
                if self.down is None:
                    self.down = str(e)
                    self.warn(f"WARNING: {e}; the run goes on, its run directory keeps "
                              "everything and it is delivered when the lab database is back")
                    self._journal("down", str(e))
                return False
            except Exception as e:  # noqa: BLE001 - a bug here must not touch the run
                self.warn(f"WARNING: delivering to the lab database failed "
                          f"({type(e).__name__}, a fault of this bench's software: please "
                          f"report it): {e}")
                return False
            if self.down is not None:
                self.down = None
                self._journal("up", None)
                self.warn("lab database: link back; what the outage held back is "
                          "delivered")
            return True

    def _journal(self, state: str, reason: str | None) -> None:
        try:
            if self.run.session:
                self.run.write(ev.LabLink(state=state, reason=reason))
        except Exception:  # noqa: BLE001 - the log closed or full: the warning said it
            pass

    def finish(self) -> bool:
        """Stop the thread and deliver what is left, with the result's registration;
        False (and a warning naming `bench records sync`) when the lab is unreachable."""
        self._stop.set()
        self._thread.join()
        ok = self.deliver(register=True)
        if not ok:
            self.warn(f"the run is not yet on the lab server: `bench records sync --runs "
                      f"{self.path.parent}` delivers it once the lab database is reachable")
        self.link.close()
        return ok
