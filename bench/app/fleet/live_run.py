"""Where a run meets the lab server: a courier for the session, when the records are one.

Kept apart from the session (bench/app/session.py enters `delivered` around a session)
so that a bench whose records are its own SQLite file starts no thread and opens no
connection.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from bench.app.fleet.sync import bench_name, is_lab_server
from bench.app.records.hooks import RecordsTarget
from bench.core.journal import RunDir

Warn = Callable[[str], None]


@contextmanager
def delivered(run: RunDir, where: RecordsTarget, stated_name: str | None, warn: Warn,
              warn_after: Warn) -> Iterator[None]:
    """Deliver the run to its records' lab database while the block runs and once at its
    end (a PostgreSQL URL; anything else: nothing happens). `warn` while the run goes on,
    `warn_after` once its console has closed."""
    if not is_lab_server(where.url):
        yield
        return
    from bench.app.fleet.courier import Courier

    courier = Courier(run, where.url, bench_name(run.path, stated_name), warn,
                      interval_for=where.interval_for).start()
    try:
        yield
    finally:
        courier.warn = warn_after
        courier.finish()


def report_lost(runs_dir: Path, where: RecordsTarget, stated_name: str | None, warn: Warn
                ) -> None:
    """At a run's start: journal every run of the runs folder whose bench process is gone
    without an end (bench/app/fleet/lost.py), say so, and deliver those runs to the lab
    database when the records are one (an unreachable one: the next sync does it)."""
    from bench.app.fleet.lost import mark_lost_runs

    lost = mark_lost_runs(runs_dir, "bench run")
    for found in lost:
        warn(f"found: {found.line}")
    if not lost or not is_lab_server(where.url):
        return
    from bench.app.fleet.outbox import Outbox
    from bench.app.fleet.sync import LabLink, SyncError

    try:
        with LabLink(where.url, where.interval_for) as link:
            for found in lost:
                link.deliver(found.run_path, Outbox(runs_dir, where.url),
                             bench_name(found.run_path, stated_name), register=False)
    except SyncError as e:
        warn(f"WARNING: {e}; `bench records sync` tells the lab later")
