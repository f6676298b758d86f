"""Where a run meets the lab server: a courier for the session, when the records are one.

Kept apart from the session (bench/app/session.py enters `delivered` around a session)
so that a bench whose records are its own SQLite file starts no thread and opens no
connection.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

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
