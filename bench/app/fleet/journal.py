"""Reading a run's event log from a byte offset: the lines not yet delivered.

An event's identity is its line number in events.jsonl, which is append-only (a resume
appends; a line torn by a crash stays where it is and the resume starts a fresh line).
Only whole lines are read: a line still being written is left for the next delivery. A
line that is not a JSON object (a torn one) keeps its number and is not delivered.
"""

from __future__ import annotations

from pathlib import Path

from bench.app.fleet.codec import JournalLine, journal_line
from bench.core.rundir_layout import EVENTS


def new_lines(run_path: Path, offset_bytes: int, seq: int, max_lines: int
              ) -> tuple[list[JournalLine], int, int]:
    """Up to `max_lines` whole lines after `offset_bytes` (the line before it numbered
    `seq`); with the offset and number after the last line returned."""
    out: list[JournalLine] = []
    try:
        with open(run_path / EVENTS, "rb") as f:
            f.seek(offset_bytes)
            while len(out) < max_lines:
                raw = f.readline()
                if not raw.endswith(b"\n"):
                    break                  # end of file, or a line being written
                offset_bytes += len(raw)
                seq += 1
                out.append(journal_line(seq, raw))
    except FileNotFoundError:
        pass
    return out, offset_bytes, seq


def size_of(run_path: Path) -> int:
    try:
        return (run_path / EVENTS).stat().st_size
    except OSError:
        return 0
