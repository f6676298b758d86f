"""A run directory -> the record the database keeps of it (`RunRecord`).

Everything comes from the run directory's own files (result.json, meta.json, stand.yaml,
the certificate files), so `bench records import` can register a run long after it
ended and get exactly what the end of the run would have registered.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import socket
from dataclasses import dataclass
from pathlib import Path

from bench.analysis.finite import finite_number as _num
from bench.app.records.checks import CheckRecord, checks_of
from bench.app.records.codec import RecordsMeta, read_records_meta
from bench.core import rundir_layout as layout
from bench.core.journal import sha256_file
from bench.core.journal_codec import RunMeta, read_meta
from bench.core.placeholders import run_copy
from bench.kind import installed_records
from bench.report.certificate.sources import read_frame
from bench.report.figures import FigureValue
from bench.report.result_frame import Check, ResultFrame
from drivers.json_types import JsonValue

#: files of a run directory that make up its certificate (hashed into the records)
CERTIFICATE_FILES = (layout.CERTIFICATE_PDF, layout.CERTIFICATE_HTML, layout.CERTIFICATE_DCC)
#: meta.json keys written by `bench run` for the records (as-found/as-left, operator)
STATES = ("as-found", "as-left")


class NotARun(ValueError):
    """A folder that is no finished run directory (no result.json to register)."""


#: the `rule` of a figure kept as its one-sided upper limit (not resolved): `value` is
#: the limit, `u` is None; printed "< value", drawn as a limit (issue 18's one rule)
UPPER_LIMIT = "upper-limit"


@dataclass(frozen=True)
class FigureRecord:
    """One reported figure with its expanded uncertainty (k = 2) and check verdict."""

    axis: str
    quantity: str            # the kind's declared key (bench/report/figures.py), unit in the name
    set_rate_dps: float | None
    value: float
    u: float | None
    unit: str                # "1" for fractions and k, "deg/s", "deg/h", "deg"
    tolerance: float | None = None
    verdict: str | None = None
    rule: str | None = None

    @property
    def is_limit(self) -> bool:
        return self.rule == UPPER_LIMIT


@dataclass(frozen=True)
class RunRecord:
    """What the records keep of one run; `uid` finds the same run again on re-import."""

    uid: str
    serial: str
    maker: str | None
    model: str | None
    location: str | None
    interval_days: int | None
    kind: str
    title: str | None
    run_dir: str
    run_path: str
    host: str
    procedure_name: str | None
    procedure_sha256: str | None
    stand_sha256: str | None
    result_sha256: str
    created_utc: dt.datetime | None
    started_utc: dt.datetime | None
    completed_utc: dt.datetime | None
    operator: str | None
    verdict: str
    calibration_state: str | None
    adjustment_note: str | None
    certificate_number: str | None
    simulated: bool
    sessions: int | None
    aborted: bool
    bench_version: str | None
    figures: tuple[FigureRecord, ...] = ()
    cert_files: tuple[tuple[str, str, int], ...] = ()   # (name, sha256, bytes)
    checks: tuple[CheckRecord, ...] = ()    # the bench's own instruments (checks.py)

    @property
    def date_utc(self) -> dt.datetime | None:
        """The date a trend is plotted against: when the measurement ended."""
        return self.completed_utc or self.started_utc or self.created_utc


def parse_utc(stamp: JsonValue | dt.datetime) -> dt.datetime | None:
    """ISO text -> naive UTC datetime (what the database stores); None if unreadable."""
    if not stamp:
        return None
    if isinstance(stamp, dt.datetime):
        t = stamp
    else:
        try:
            t = dt.datetime.fromisoformat(str(stamp).replace("Z", "+00:00"))
        except ValueError:
            return None
    if t.tzinfo is not None:
        t = t.astimezone(dt.UTC).replace(tzinfo=None)
    return t


def run_uid(meta: RunMeta, run_dir: str) -> str:
    """Stable over re-analysis and re-import, distinct between benches: the random uid
    meta.json was given when the run was created; for a run from before it, creation time
    to the millisecond, directory name and the input files' digests."""
    own = meta.get("run_uid")
    if own:
        return own
    key = "|".join((meta.get("created_utc", ""), meta.get("procedure_sha256", ""),
                    meta.get("stand_sha256", ""))) + "|" + run_dir
    return hashlib.sha256(key.encode()).hexdigest()[:32]


def _checks_index(frame: ResultFrame) -> dict[tuple[str, str, float | None], Check]:
    """checks[] by (axis, quantity, set rate): the verdict beside each figure."""
    return {("" if c.axis is None else c.axis, str(c.quantity), c.set_rate_dps): c
            for c in frame.checks}


def _record(f: FigureValue, checks: dict[tuple[str, str, float | None], Check]
            ) -> FigureRecord:
    """The row the records keep: the kind's figure with its check's tolerance and verdict."""
    c = checks.get((f.axis, f.check, f.set_rate_dps)) if f.check else None
    if c is None and f.check:
        c = checks.get((f.axis, f.check, None)) or checks.get((f.axis, f.check, 0.0))
    return FigureRecord(f.axis, f.quantity, f.set_rate_dps, f.value, f.u, f.unit,
                        c.tolerance if c is not None else None,
                        c.verdict if c is not None and c.verdict else None,
                        UPPER_LIMIT if f.upper_limit else (
                            c.rule if c is not None and c.rule else None))


def kind_name(frame: ResultFrame, run_path: Path | None = None) -> str:
    """The procedure kind of a result: the one it names, else (an older result) the one
    the certificate takes it for (`bench.app.certificate.build.procedure_of`: the procedure
    file's, or the installed kind that recognises its keys); "" if none does."""
    from bench.app.certificate.build import Sources, procedure_of

    if frame.procedure:
        return frame.procedure
    try:
        return procedure_of(Sources.load(frame.doc, run_path)).name
    except Exception:  # noqa: BLE001 - a malformed result is registered under no kind
        return ""


def figures_of(frame: ResultFrame, kind: str | None = None) -> list[FigureRecord]:
    """Every figure the kind reports of a result (its `records` part,
    bench.kind.RecordsPart), with U (k = 2) and its check's verdict; none when the kind
    is not installed here."""
    return frame_figures(frame, kind if kind is not None else kind_name(frame))


def frame_figures(frame: ResultFrame, kind: str) -> list[FigureRecord]:
    """`figures_of` of a result the reader has decoded (its frame)."""
    reporter = installed_records(kind)
    if reporter is None:
        return []
    checks = _checks_index(frame)
    return [_record(f, checks) for f in reporter.figure_values(frame)]


def certificate_number(run_path: Path) -> str | None:
    """The number of the run's latest issued revision; None while it has only a draft (a
    draft is no certificate: the records and a later run's history never cite one)."""
    from bench.app.certificate import register

    done = [i for i in register.issues(run_path) if not i.draft]
    return done[-1].number if done else None


def _issued_files(path: Path, number: str | None) -> tuple[tuple[str, str, int], ...]:
    """(name, SHA-256, bytes) of the issued revision's files as stored under
    issued/<number>/; nothing for a draft."""
    if number is None:
        return ()
    folder = path / layout.ISSUED / number
    return tuple((name, sha256_file(folder / name), (folder / name).stat().st_size)
                 for name in CERTIFICATE_FILES if (folder / name).is_file())


def record_of(run_path: str | Path, frame: ResultFrame | None = None) -> RunRecord:
    """The record of a finished run directory (its result's frame as the analysis gave it,
    else result.json's); NotARun if it has no result.json."""
    path = Path(run_path).resolve()
    if frame is None:
        if not (path / layout.RESULT).is_file() or not (path / layout.EVENTS).is_file():
            raise NotARun(f"{path}: no result.json and events.jsonl (not a finished run)")
        frame = read_frame(path / layout.RESULT)
    if frame is None or not frame.doc:
        raise NotARun(f"{path}/result.json: not a readable result")
    result = frame.doc
    meta = read_records_meta(path / layout.META) or RecordsMeta()
    stand_file = run_copy(path, layout.STAND)   # a serial still to fill in is none
    ident = dict((stand_file.get("stand") or {}) if isinstance(stand_file, dict) else {})
    ident.update({k: v for k, v in frame.stand.items() if v is not None})
    serial = str(ident.get("serial") or "").strip()
    if not serial:
        raise NotARun(f"{path}: the stand has no serial number (stand.serial)")
    interval = ident.get("recertification_interval_days")
    dates = frame.dates
    state = meta.calibration_state or frame.records.get("calibration_state")
    number = certificate_number(path)
    cert_files = _issued_files(path, number)
    blob = json.dumps(result, sort_keys=True, default=str).encode()
    kind = frame.procedure or kind_name(frame, path)
    return RunRecord(
        uid=run_uid(_run_meta(path), path.name),
        serial=serial,
        maker=_opt(ident.get("maker")), model=_opt(ident.get("model")),
        location=_opt(ident.get("location")),
        interval_days=int(iv) if (iv := _num(interval)) else None,
        kind=kind,
        title=_opt(frame.title),
        run_dir=path.name, run_path=str(path), host=socket.gethostname(),
        procedure_name=_opt(meta.procedure_name),
        procedure_sha256=_opt(meta.procedure_sha256),
        stand_sha256=_opt(meta.stand_sha256),
        result_sha256=hashlib.sha256(blob).hexdigest(),
        created_utc=parse_utc(dates.created_utc or meta.created_utc),
        started_utc=parse_utc(dates.started_utc),
        completed_utc=parse_utc(dates.completed_utc),
        operator=_opt(meta.operator),
        verdict=frame.verdict or "incomplete",
        calibration_state=state if state in STATES else None,
        adjustment_note=_opt(meta.adjustment_note),
        certificate_number=number,
        simulated=frame.simulated,
        sessions=frame.sessions or None,
        aborted=frame.aborted,
        bench_version=_opt(meta.bench_version),
        figures=tuple(frame_figures(frame, kind)),
        cert_files=cert_files,
        checks=tuple(checks_of(path, frame, stand_file if isinstance(stand_file, dict)
                               else {}, kind)),
    )


def _run_meta(path: Path) -> RunMeta:
    """meta.json's own keys (none when it is missing or not meta.json's shape: the run's
    uid is then made from its folder's name, as for a run from before uids)."""
    try:
        return read_meta(path / layout.META)
    except (OSError, ValueError):
        return RunMeta()


def _opt(x: JsonValue) -> str | None:
    return None if x is None or x == "" else str(x)


def find_runs(runs_dir: str | Path) -> list[Path]:
    """Run directories under `runs_dir` (itself, its children, or deeper), oldest first."""
    root = Path(runs_dir)
    found = {p.parent for p in root.rglob(layout.RESULT) if (p.parent / layout.EVENTS).is_file()}
    return sorted(found, key=lambda p: (_created_utc(p), p.name))


def _created_utc(run_path: Path) -> str:
    meta = read_records_meta(run_path / layout.META)
    return (meta.created_utc if meta is not None else None) or ""
