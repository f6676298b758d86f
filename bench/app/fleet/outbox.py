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
import json
import os
from dataclasses import asdict, dataclass
from pathlib import Path

from bench.app.db import redact

OUTBOX_DIR = ".outbox"


def lab_key(url: str) -> str:
    """A short name for a lab database in file names (its URL without the password)."""
    return hashlib.sha256(redact(url).encode()).hexdigest()[:12]


@dataclass(frozen=True)
class Cursor:
    """What one lab database holds of one run."""

    offset_bytes: int = 0             # events.jsonl delivered up to here (whole lines)
    seq: int = 0                      # the line number of the last line delivered
    result_sha256: str | None = None  # result.json as delivered
    registered_sha256: str | None = None   # result.json as registered in the records


class Outbox:
    """The cursors of one runs folder towards one lab database."""

    def __init__(self, runs_dir: Path, url: str) -> None:
        self.folder = Path(runs_dir) / OUTBOX_DIR
        self.key = lab_key(url)

    def path(self, run_name: str) -> Path:
        return self.folder / f"{run_name}.{self.key}.json"

    def cursor(self, run_name: str) -> Cursor:
        """The run's cursor; a missing or unreadable file is a fresh start (a resend)."""
        try:
            data = json.loads(self.path(run_name).read_text())
            return Cursor(**{k: data[k] for k in Cursor.__dataclass_fields__ if k in data})
        except (OSError, ValueError, TypeError):
            return Cursor()

    def save(self, run_name: str, cursor: Cursor) -> None:
        """Replace the cursor atomically (written after the database committed)."""
        self.folder.mkdir(parents=True, exist_ok=True)
        target = self.path(run_name)
        tmp = target.with_suffix(f".{os.getpid()}.tmp")
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(asdict(cursor), f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
