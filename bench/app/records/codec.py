"""RUN_DIR/assurance.json <-> its model, by msgspec (issue 60): what the records say of
each instrument a run rests on, written at the end of a run and by `bench authorise`,
read by the certificate (assurance_notes.py) and by the authorisation's refusal; and the
marks a run's start adds to its meta.json (`RunMarks`, hooks.mark_run).

Why a module of its own: it is the one place where this file's JSON meets a typed value
(tests/test_json_boundary.py keeps JSON maps out of every other module). The file is
written as before (`json.dumps`, indent 2, the keys in the Structs' field order); an
unreadable or malformed file reads as none (the certificate then says "not assessed").
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import msgspec
from msgspec import UNSET, UnsetType


class ReviewLine(msgspec.Struct, frozen=True, kw_only=True):
    """The last review recorded of an instrument: when, who, why, through which run."""

    utc: str
    reviewer: str
    text: str
    through_utc: str | None = None


class InstrumentLine(msgspec.Struct, frozen=True, kw_only=True):
    """One instrument's control status as the certificate prints it (`line`)."""

    serial: str = ""
    role: str = ""
    model: str | None = None
    state: str = ""
    runs: int = 0
    rule: str | None = None
    line: str = ""
    open_signals: tuple[str, ...] = ()
    reviewed_signals: tuple[str, ...] = ()
    last_review: ReviewLine | None = None


class Assurance(msgspec.Struct, frozen=True, kw_only=True):
    """The file: the records read (redacted), when, and each instrument's status or the
    reason none could be assessed."""

    records: str = ""
    assessed_utc: str = ""
    instruments: tuple[InstrumentLine, ...] | UnsetType = UNSET
    error: str | UnsetType = UNSET


class RunMarks(msgspec.Struct, frozen=True, kw_only=True):
    """What the operator and the register said at a run's start, added to meta.json in
    this order (the procedure file's operator only when it names one)."""

    calibration_state: str | None
    adjustment_note: str | None
    os_user: str | None
    operator: str | None
    operator_stated: str | UnsetType = UNSET


def mark_meta_file(path: Path, marks: RunMarks, register: Mapping[str, object]) -> None:
    """meta.json with the marks and the register's entries added (a key it has keeps its
    place), written back as `RunDir.create` writes it (indent 2, a newline)."""
    _add_to_meta(path, {**msgspec.to_builtins(marks), **register})


def _add_to_meta(path: Path, added: Mapping[str, object]) -> None:
    """meta.json with `added` (a key it has keeps its place, a new one goes last), written
    back as `RunDir.create` writes it (indent 2, a newline)."""
    meta = json.loads(path.read_text())
    meta.update(added)
    path.write_text(json.dumps(meta, indent=2) + "\n")


def write_assurance_file(path: Path, doc: Assurance) -> None:
    path.write_text(json.dumps(msgspec.to_builtins(doc), indent=2) + "\n", encoding="utf-8")


def read_assurance_file(path: Path) -> Assurance | None:
    """The file as written; None when there is none or it is not one."""
    try:
        return msgspec.json.decode(path.read_bytes(), type=Assurance)
    except (OSError, msgspec.DecodeError):
        return None


class RecordsMeta(msgspec.Struct, frozen=True, kw_only=True):
    """What the records read of a run's meta.json: the keys `RunDir.create` and the run's
    start (`RunMarks`) write, and the drifting twin's run number. A key an older run
    lacks reads as None."""

    created_utc: str | None = None
    procedure_name: str | None = None
    procedure_sha256: str | None = None
    stand_sha256: str | None = None
    bench_version: str | None = None
    calibration_state: str | None = None
    adjustment_note: str | None = None
    operator: str | None = None
    sim_run_number: int | None = None


def read_records_meta(path: Path) -> RecordsMeta | None:
    """meta.json's keys for the records; None when it is missing, damaged or not of
    meta.json's shape (a hand-edited file: the record is then made without them, as for a
    run with no meta.json)."""
    try:
        return msgspec.json.decode(path.read_bytes(), type=RecordsMeta)
    except (OSError, msgspec.DecodeError):
        return None


def add_sim_run_number(path: Path, number: int) -> None:
    """meta.json with the drifting twin's run number added last (a --resume drifts the
    same way as the first session), written back as `RunDir.create` writes it."""
    _add_to_meta(path, {"sim_run_number": number})
