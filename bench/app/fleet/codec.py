"""What the fleet's delivery reads and writes as JSON, typed (issue 60): an event line as
delivered to the lab database, the outbox's cursor file, result.json as stored with a run.

An event line is delivered as written (its body is the lab's copy of the evidence, and
`bench records check` compares the two), so the line's JSON object travels whole, with
the few facts the delivery files it under (its kind's name, its UTC stamp) read here.
The outbox's file is written with `json.dump` as before, so its bytes do not change.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import msgspec

from bench.app.fleet.health import HealthSample
from bench.core.events import name_of
from drivers.json_types import JsonObject, JsonValue


class JournalLine(msgspec.Struct, frozen=True):
    """One line of a run's event log: its number (1 = first) and the record as written,
    None for a line that is no record (a torn one keeps its number, is not delivered)."""

    seq: int
    body: JsonObject | None

    @property
    def name(self) -> str:
        """The event kind the line names, declared here or not ('not an event' if none)."""
        return name_of(self.body) if self.body is not None else "not an event"

    @property
    def utc(self) -> str | None:
        stamp = self.body.get("utc") if self.body is not None else None
        return stamp if isinstance(stamp, str) else None

    @property
    def text(self) -> str:
        """The record in one canonical form (keys sorted), for comparing two copies."""
        return json.dumps(self.body, sort_keys=True) if self.body is not None else "\0torn"


def journal_line(seq: int, raw: bytes) -> JournalLine:
    """Line `seq` of events.jsonl, as read from the file."""
    try:
        rec = json.loads(raw)
    except (ValueError, UnicodeDecodeError):
        rec = None
    return JournalLine(seq, rec if isinstance(rec, dict) else None)


def stored_line(seq: int, body: JsonValue) -> JournalLine:
    """Line `seq` as the lab database holds it (its JSON column)."""
    return JournalLine(seq, body if isinstance(body, dict) else None)


class Cursor(msgspec.Struct, frozen=True):
    """What one lab database holds of one run."""

    offset_bytes: int = 0             # events.jsonl delivered up to here (whole lines)
    seq: int = 0                      # the line number of the last line delivered
    result_sha256: str | None = None  # result.json as delivered
    registered_sha256: str | None = None   # result.json as registered in the records


def read_cursor(path: Path) -> Cursor:
    """The cursor in an outbox file; a missing or unreadable one is a fresh start."""
    try:
        return msgspec.json.decode(path.read_bytes(), type=Cursor)
    except (OSError, msgspec.DecodeError):
        return Cursor()


def write_cursor(path: Path, cursor: Cursor) -> None:
    """Replace the outbox file atomically, synced (written after the database committed)."""
    tmp = path.with_suffix(f".{os.getpid()}.tmp")
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(msgspec.to_builtins(cursor), f)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def stored_health(value: JsonValue) -> HealthSample | None:
    """A bench's health sample as the lab database holds it (None: none, or not one)."""
    try:
        return msgspec.convert(value, HealthSample)
    except msgspec.ValidationError:
        return None


class RawFile(msgspec.Struct, frozen=True):
    """A raw file result.json lists, with the SHA-256 it had when analysed."""

    path: str
    sha256: str | None = None


class StoredResult(msgspec.Struct, frozen=True):
    """result.json as the delivery stores it with a run (the document whole) and as the
    check reads it: its verdict, the raw files it lists (`raw_files`; an entry that is
    not one is left out of `raw_files`, its path kept in `named`)."""

    document: JsonObject
    verdict: str | None
    raw_files: tuple[RawFile, ...]
    named: frozenset[str]


def stored_result(doc: JsonValue) -> StoredResult | None:
    """A result document (a file's, or the lab's JSON column); None if it is no object."""
    if not isinstance(doc, dict):
        return None
    verdict = doc.get("verdict")
    listed = doc.get("raw_files")
    entries = [x for x in listed if isinstance(x, dict)] if isinstance(listed, list) else []
    files = []
    for x in entries:
        try:
            files.append(msgspec.convert(x, RawFile))
        except msgspec.ValidationError:
            continue
    return StoredResult(doc, str(verdict) if verdict else None, tuple(files),
                        frozenset(str(x.get("path")) for x in entries))


def read_result(path: Path) -> StoredResult | None:
    """result.json of a run directory; None when it is none or not a JSON object. Raises
    OSError when it cannot be read and ValueError when it is not JSON (being replaced)."""
    return stored_result(json.loads(path.read_text(encoding="utf-8")))
