"""The bench's outbox: how far each run has been delivered to a lab database.

A run directory is written first and is the evidence; the outbox only says what the lab
database already holds of it, so a delivery resumes where the last one stopped instead
of sending a long event log again. One small JSON file per run and lab database,
`RUNS/.outbox/<run>.<lab>.json`, replaced atomically after each committed delivery. It can
lag the database (a bench killed between the commit and the write) but never lead it:
what is sent again is dropped by the database's key (bench, run, line number), and a
lost or deleted outbox costs a full resend, never a duplicate.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from bench.app.db import redact
from bench.app.fleet.codec import Cursor, read_cursor, write_cursor

OUTBOX_DIR = ".outbox"


def lab_key(url: str) -> str:
    """A short name for a lab database in file names (its URL without the password)."""
    return hashlib.sha256(redact(url).encode()).hexdigest()[:12]


class Outbox:
    """The cursors of one runs folder towards one lab database."""

    def __init__(self, runs_dir: Path, url: str) -> None:
        self.folder = Path(runs_dir) / OUTBOX_DIR
        self.key = lab_key(url)

    def path(self, run_name: str) -> Path:
        return self.folder / f"{run_name}.{self.key}.json"

    def cursor(self, run_name: str) -> Cursor:
        """The run's cursor; a missing or unreadable file is a fresh start (a resend)."""
        return read_cursor(self.path(run_name))

    def save(self, run_name: str, cursor: Cursor) -> None:
        """Replace the cursor atomically (written after the database committed)."""
        self.folder.mkdir(parents=True, exist_ok=True)
        write_cursor(self.path(run_name), cursor)
