"""What a bench samples of its instruments for the lab's station, with each delivery.

The station on the lab server cannot read a bench's raw files, and the files are what
shows that an instrument is still talking (bench/app/station/live.py reads their ages
on the bench's own machine). So the bench reads those ages itself and delivers them with
its events: per raw file of the session now running, the wall seconds since it was last
written, and the same for the event log. Only file sizes and times are read: a sample
costs the run nothing.
"""

from __future__ import annotations

import datetime as dt
import time
from pathlib import Path
from typing import TypedDict

from bench.core.rundir_layout import EVENTS, SESSION_GLOB, raw_root


class HealthSample(TypedDict):
    """What the bench says of a run's raw files between events (the station ages it)."""

    files: dict[str, float]
    events_age_s: float | None
    sampled_utc: str


def sample(run_path: Path, now: float | None = None) -> HealthSample:
    """{"files": {raw file name: age s}, "events_age_s": age s, "sampled_utc": ISO}: the
    newest session's raw files (raw/s<N>/), ages in wall seconds at sampling."""
    now = time.time() if now is None else now
    files: dict[str, float] = {}
    sessions = sorted((p for p in raw_root(run_path).glob(SESSION_GLOB) if p.name[1:].isdigit()),
                      key=lambda p: int(p.name[1:]))
    if sessions:
        for f in sorted(sessions[-1].iterdir()):
            try:
                files[f.name] = round(max(0.0, now - f.stat().st_mtime), 3)
            except OSError:
                continue
    try:
        events_age: float | None = round(max(0.0, now - (run_path / EVENTS).stat().st_mtime), 3)
    except OSError:
        events_age = None
    return {"files": files, "events_age_s": events_age,
            "sampled_utc": dt.datetime.fromtimestamp(now, dt.UTC).isoformat(
                timespec="milliseconds")}
