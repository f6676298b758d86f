"""A run directory's JSON files as typed values and back (issue 60): the journal's lines
(events.jsonl as its kinds' records, bench/core/events.py), the raw JSON-lines logs,
meta.json and the documents a run writes.

Everything that reads a run's JSON goes through here and gets typed values back; the rest
of the code reads attributes. A reader of a run never fails on what a crash leaves: a torn
last line, a line a resume once appended onto one, a record of the wrong shape are skipped
(and counted where the caller reports them), never raised.

Written with `json.dumps` as before (msgspec's own float format differs: 1e-05 against
0.00001), so every line and file keeps the bytes it had.
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import TypedDict, TypeVar

import msgspec

from bench.core import events as ev
from bench.core.events import Event
from drivers.json_types import JsonObject, JsonScalar, JsonValue

T = TypeVar("T")
S = TypeVar("S", bound=msgspec.Struct)


# -- writing ------------------------------------------------------------------------------

def encode_line(record: Mapping[str, object]) -> str:
    """One JSON line as the journals have always written it (compact, no NaN)."""
    return json.dumps(record, separators=(",", ":"), allow_nan=False) + "\n"


def encode_event(record: Event) -> str:
    """An event's line: its frame first, then its kind's fields (`events.encode`)."""
    return encode_line(ev.encode(record))


def encode_document(data: object) -> str:
    """A JSON file a run writes whole (result.json, meta.json): indented, no NaN."""
    return json.dumps(data, indent=2, allow_nan=False) + "\n"


# -- JSON lines ---------------------------------------------------------------------------

def _record(line: str | bytes) -> JsonObject | None:
    """A line's JSON object, or None when it is none (torn, not JSON, not an object)."""
    try:
        rec = json.loads(line)
    except (ValueError, UnicodeDecodeError):
        return None
    return rec if isinstance(rec, dict) else None


def scan_jsonl(path: Path) -> tuple[list[JsonObject], list[int]]:
    """Records of a JSON-lines file, and the numbers of the lines that are not records
    (a torn last line after a crash or power loss mid-write, or a line a resume once
    appended onto one). A reader tolerates them and reports them; it never crashes."""
    records: list[JsonObject] = []
    bad: list[int] = []
    with open(path, encoding="utf-8", errors="replace") as f:
        for n, line in enumerate(f, 1):
            rec = _record(line)
            if rec is not None:
                records.append(rec)
            elif line.strip():
                bad.append(n)
    return records, bad


def read_jsonl(path: Path) -> Iterator[JsonObject]:
    """Records of a JSON-lines file; a torn line (a crash mid-write) is skipped."""
    yield from scan_jsonl(path)[0]


def read_json_object(path: Path) -> JsonObject:
    """A JSON object file this run wrote (result.json): a damaged one is an error."""
    data = json.loads(path.read_text(encoding="utf-8"))
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a JSON object, found {type(data).__name__}")
    return data


def tail_lines(path: Path, max_bytes: int) -> list[bytes]:
    """The whole lines in the last `max_bytes` of a file (the first, cut, skipped): a
    growing log is read in constant time; none when the file does not exist."""
    try:
        size = path.stat().st_size
        with open(path, "rb") as f:
            start = max(0, size - max_bytes)
            f.seek(start)
            data = f.read(size - start)
    except FileNotFoundError:
        return []
    lines = data.split(b"\n")
    return lines[1:] if start > 0 else lines


def tail_records(path: Path, max_bytes: int, cls: type[S]) -> list[S]:
    """The records in the last `max_bytes` of a JSON-lines file that read as `cls` (a
    torn line, or one of another shape, skipped)."""
    out: list[S] = []
    for line in tail_lines(path, max_bytes):
        rec = _record(line)
        if rec is None:
            continue
        try:
            out.append(msgspec.convert(rec, cls))
        except msgspec.ValidationError:
            continue
    return out


# -- events.jsonl ---------------------------------------------------------------------------

def decode_event(line: str | bytes) -> Event | None:
    """One line of events.jsonl as its kind's record; None for a line that is no record."""
    rec = _record(line)
    return None if rec is None else ev.decode(rec)


def scan_events(path: Path) -> tuple[list[Event], list[int]]:
    """events.jsonl's records, and the numbers of its lines that are none (`scan_jsonl`)."""
    records, bad = scan_jsonl(path)
    return ev.decode_all(records), bad


def read_events(path: Path) -> list[Event]:
    """A run's events.jsonl, each line as its kind's record (bench/core/events.py)."""
    return scan_events(path)[0]


def tail_events(path: Path, max_bytes: int) -> list[Event]:
    """The events in the last `max_bytes` of events.jsonl (a torn line skipped)."""
    found = (decode_event(line) for line in tail_lines(path, max_bytes))
    return [e for e in found if e is not None]


# -- raw logs --------------------------------------------------------------------------------

class MalformedRecord(ValueError):
    """A journal record whose field is not of the type its writer gives it."""


def _narrow(rec: Mapping[str, object], key: str, kind: type[T], what: str) -> T:
    """`rec[key]` as the type its writer gives it (a bool is no number: JSON tells them
    apart); the record's reader narrows each field once, here."""
    v = rec[key]
    if not isinstance(v, kind) or (isinstance(v, bool) and kind is not bool):
        raise MalformedRecord(f"{key!r} is {v!r}, not {what}")
    return v


def str_field(rec: Mapping[str, object], key: str) -> str:
    return _narrow(rec, key, str, "a string")


def float_field(rec: Mapping[str, object], key: str) -> float:
    """A number as written (JSON writes 1.0 as 1: an integer is one too)."""
    v = rec[key]
    if isinstance(v, int) and not isinstance(v, bool):
        return v
    return _narrow(rec, key, float, "a number")


class DriveFeedback(msgspec.Struct, frozen=True):
    """A line of a drive's raw log (raw/s<N>/<axis>-drive.jsonl) as the settling plot reads
    it: `kind` "feedback" for a velocity reading (TPDO); other kinds (commands, EMCY)
    carry neither number."""

    kind: str = ""
    t_s: float | None = None
    velocity_dps: float | None = None


class DriveLine(msgspec.Struct, frozen=True):
    """A line of a drive's raw log as the records' check values read it (docs/method.md
    C1): a `command` (its time, the rate sent, the acceleration), a `settled` report
    (target, hold, samples) or a `feedback` reading; a key a kind lacks reads None."""

    kind: str = ""
    t_s: float | None = None
    sent_dps: float | None = None
    accel_dps2: float | None = None
    target_dps: float | None = None
    hold_s: float | None = None
    samples: float | None = None
    velocity_dps: float | None = None


def read_drive_log(path: Path) -> Iterator[DriveLine]:
    """A drive's raw log, line by line: a torn line, or one whose keys are of the wrong
    type, is skipped."""
    decoder = msgspec.json.Decoder(DriveLine)
    with open(path, "rb") as f:
        for line in f:
            try:
                yield decoder.decode(line)
            except msgspec.DecodeError:
                continue


# -- result.json ------------------------------------------------------------------------------

class _Verdict(msgspec.Struct):
    verdict: str | None = None


def read_verdict(path: Path) -> str | None:
    """result.json's verdict, None when there is no readable result (none yet, one being
    replaced, a damaged file): the rest of the document is not decoded."""
    try:
        return msgspec.json.decode(path.read_bytes(), type=_Verdict).verdict
    except (OSError, msgspec.DecodeError):
        return None


# -- meta.json --------------------------------------------------------------------------------

class RunMeta(TypedDict, total=False):
    """meta.json as `RunDir.create` writes it: where the inputs came from, their SHA-256,
    the version (the run's later facts, as-found/as-left, the performer, are added by the
    app and read where they are used). Read back, a key an older run lacks is absent."""

    procedure_file: str
    procedure_name: str
    procedure_sha256: str
    stand_file: str
    stand_sha256: str
    created_utc: str
    bench_version: str
    #: the run's own identity, random: distinct for two benches that start the same
    #: procedure and stand in the same second (their folders may share a name)
    run_uid: str


def read_meta(path: Path) -> RunMeta:
    """A run's meta.json (its own keys typed; what the app added later left out). Raises
    OSError when it cannot be read and ValueError when it is not meta.json's shape."""
    try:
        return msgspec.json.decode(path.read_bytes(), type=RunMeta)
    except msgspec.DecodeError as e:
        raise ValueError(f"{path}: {e}") from e


class PerformerMeta(msgspec.Struct, frozen=True):
    """meta.json's `performer`: the account the lab register authenticated at the run's
    start (bench/app/register/gate.py writes it)."""

    full_name: str | None = None
    account: str | None = None
    register: str | None = None
    authenticated_utc: str | None = None


class EquipmentStatusMeta(msgspec.Struct, frozen=True):
    """One entry of meta.json's `equipment_status`: why the inventory did not clear an
    item, or the deviation it was used under, and the calibration in force (its
    certificate, issuer and due date) at the stand key `where`."""

    problem: str | None = None
    deviation: str | None = None
    where: str | None = None
    certificate: str | None = None
    issuer: str | None = None
    due: str | None = None


class StartMeta(msgspec.Struct, frozen=True):
    """What the app adds to meta.json at the run's start: who performed it (the register's
    account, else the operating-system user or --operator) and the equipment's status."""

    performer: PerformerMeta | None = None
    equipment_register: str | None = None
    equipment_status: tuple[EquipmentStatusMeta, ...] = ()
    os_user: str | None = None
    operator: str | None = None


def start_meta(meta: JsonObject) -> StartMeta:
    """meta.json's start facts, typed. A part of the wrong shape is left out (the
    certificate says "not recorded"), never a crash that withholds the certificate."""
    try:
        return msgspec.convert(meta, StartMeta)
    except msgspec.ValidationError:
        pass

    def fits(value: JsonValue, model: type[msgspec.Struct]) -> bool:
        try:
            msgspec.convert(value, model)
        except msgspec.ValidationError:
            return False
        return True

    found = meta.get("equipment_status")
    statuses = [e for e in (found if isinstance(found, list) else [])
                if isinstance(e, dict) and fits(e, EquipmentStatusMeta)]
    parts = {n: meta.get(n) for n in StartMeta.__struct_fields__
             if n != "equipment_status" and fits({n: meta.get(n)}, StartMeta)}
    return msgspec.convert({**parts, "equipment_status": statuses}, StartMeta)


def json_leaves(raw: bytes) -> dict[str, JsonScalar]:
    """A JSON document's values by key path (`a.b[0].c`), in the document's order: what
    two issued revisions' result.json are compared by. ValueError when it is not JSON."""
    def walk(node: JsonValue, path: str) -> Iterator[tuple[str, JsonScalar]]:
        if isinstance(node, dict):
            for k, v in node.items():
                yield from walk(v, f"{path}.{k}" if path else str(k))
        elif isinstance(node, list):
            for i, v in enumerate(node):
                yield from walk(v, f"{path}[{i}]")
        else:
            yield path, node

    doc: JsonValue = json.loads(raw)
    return dict(walk(doc, ""))
