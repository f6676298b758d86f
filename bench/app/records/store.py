"""The records store: one code path for SQLite and PostgreSQL (SQLAlchemy Core).

`Records.open(url)` connects and brings the schema to the newest migration (Alembic,
in-process, the scripts shipped in this package), so a database created by any earlier
version is upgraded before it is used. Registration is one transaction per run and is
retried when a concurrent writer got there first (a table's first row, a locked SQLite
file): two benches registering at once both end up recorded.
"""

from __future__ import annotations

import datetime as dt
import random
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import sqlalchemy as sa
from sqlalchemy.engine import Connection, Engine, RowMapping
from sqlalchemy.exc import DBAPIError, IntegrityError, OperationalError

from bench.app.db import make_engine, reason_in_words, redact, upgrade_to_head
from bench.app.records import schema as s
from bench.app.records.checks import CheckRecord
from bench.app.records.extract import FigureRecord, RunRecord

MIGRATIONS = Path(__file__).resolve().parent / "migrations"
RETRIES = 8
T = TypeVar("T")


class RecordsError(RuntimeError):
    """The records database cannot be reached or used; the message says which and why."""


def _retrying(what: str, fn: Callable[[], T]) -> T:
    """Run `fn` again when a concurrent writer won a race; other errors pass through."""
    for attempt in range(RETRIES):
        try:
            return fn()
        except (IntegrityError, OperationalError) as e:
            if attempt == RETRIES - 1 or not _is_race(e):
                raise
            time.sleep(0.05 * (2 ** attempt) * (0.5 + random.random()))
    raise AssertionError("unreachable")


def _is_race(e: DBAPIError) -> bool:
    if isinstance(e, IntegrityError):
        return True
    text = str(e.orig).lower()
    return any(m in text for m in ("locked", "deadlock", "could not serialize", "busy"))


def _utc(t: dt.datetime | None) -> dt.datetime | None:
    """Naive UTC from the database -> aware UTC for readers."""
    return None if t is None else t.replace(tzinfo=dt.UTC)


def _now() -> dt.datetime:
    return dt.datetime.now(dt.UTC).replace(tzinfo=None)


# -- the read API's records -----------------------------------------------------------------

@dataclass(frozen=True)
class TableInfo:
    """One calibrated table (asset) and its recertification state."""

    serial: str
    maker: str | None
    model: str | None
    location: str | None
    interval_days: int | None
    runs: int
    last_run_utc: dt.datetime | None
    last_pass_utc: dt.datetime | None
    last_certificate: str | None


@dataclass(frozen=True)
class RunInfo:
    """One registered run of a table."""

    id: int
    uid: str
    serial: str
    kind: str
    title: str | None
    run_dir: str
    run_path: str | None
    host: str | None
    procedure_name: str | None
    procedure_sha256: str | None
    date_utc: dt.datetime | None
    started_utc: dt.datetime | None
    completed_utc: dt.datetime | None
    registered_utc: dt.datetime
    operator: str | None
    verdict: str
    calibration_state: str | None
    adjustment_note: str | None
    certificate_number: str | None
    simulated: bool
    cert_files: dict[str, str]      # name -> SHA-256


@dataclass(frozen=True)
class TrendPoint:
    """One figure of one run, placed in time: the unit of a trend."""

    run_uid: str
    date_utc: dt.datetime | None
    certificate_number: str | None
    calibration_state: str | None
    figure: FigureRecord


@dataclass(frozen=True)
class DueItem:
    """A table's next recertification."""

    table: TableInfo
    due_date: dt.date | None          # None: never passed, due now
    days_left: int | None             # negative: overdue by that many days

    @property
    def status(self) -> str:
        if self.days_left is None:
            return "due (no passing run recorded)"
        if self.days_left < 0:
            return f"OVERDUE by {-self.days_left} d"
        return f"due in {self.days_left} d"


@dataclass(frozen=True)
class InstrumentInfo:
    """One of the bench's own instruments, known by its check values."""

    serial: str
    role: str
    model: str | None
    first_seen_utc: dt.datetime | None
    last_seen_utc: dt.datetime | None


@dataclass(frozen=True)
class CheckPoint:
    """One check value placed in time: a point of a control chart."""

    run_uid: str
    run_dir: str
    table_serial: str
    date_utc: dt.datetime | None
    check: CheckRecord
    #: from a run on the twins: kept out of a real run's control-chart baseline
    simulated: bool = False


@dataclass(frozen=True)
class ReviewInfo:
    """A recorded review of an instrument's control status: who, when, why."""

    serial: str
    utc: dt.datetime
    reviewer: str
    text: str
    status: str | None
    through_utc: dt.datetime | None
    new_baseline: bool = False        # the charts restart at the last run it saw


class Records:
    """The records database. Write: `register`. Read: `tables`, `runs`, `trend`, `due`."""

    def __init__(self, engine: Engine, url: str) -> None:
        self.engine = engine
        self.url = url

    @classmethod
    def open(cls, url: str) -> Records:
        """Connect and migrate to the newest schema; RecordsError if that cannot be done."""
        try:
            engine = make_engine(url)
        except Exception as e:  # noqa: BLE001 - a bad URL is a reachability problem too
            raise RecordsError(f"records database {redact(url)}: {e}") from e
        rec = cls(engine, url)
        try:
            _retrying("migrate", rec.migrate)
        except Exception as e:  # noqa: BLE001
            engine.dispose()
            raise RecordsError(f"records database {redact(url)}: {_short(e)}") from e
        return rec

    def close(self) -> None:
        self.engine.dispose()

    def __enter__(self) -> Records:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def migrate(self) -> None:
        upgrade_to_head(self.engine, MIGRATIONS)

    def revision(self) -> str | None:
        from alembic.runtime.migration import MigrationContext

        with self.engine.connect() as conn:
            ctx = MigrationContext.configure(
                conn, opts={"version_table": "records_alembic_version"})
            return ctx.get_current_revision()

    @contextmanager
    def _tx(self) -> Iterator[Connection]:
        with self.engine.begin() as conn:
            yield conn

    # -- writing --------------------------------------------------------------------------
    def register(self, rec: RunRecord, interval_days: int | None = None) -> str:
        """Record one run (idempotent): 'new', 'updated' (re-analysed) or 'unchanged'."""
        return _retrying("register", lambda: self._register(rec, interval_days))

    def _register(self, rec: RunRecord, interval_days: int | None) -> str:
        now = _now()
        with self._tx() as conn:
            table_id = self._table_id(conn, rec, interval_days, now)
            old = conn.execute(sa.select(s.runs.c.id, s.runs.c.result_sha256)
                               .where(s.runs.c.uid == rec.uid)).first()
            old_files = {}
            if old is not None:
                old_files = {r.name: r.sha256 for r in conn.execute(
                    sa.select(s.cert_files.c.name, s.cert_files.c.sha256)
                    .where(s.cert_files.c.run_id == old.id))}
                if old.result_sha256 == rec.result_sha256 and old_files == {
                        n: h for n, h, _ in rec.cert_files}:
                    if not rec.checks or conn.execute(sa.select(s.checks.c.id).where(
                            s.checks.c.run_id == old.id).limit(1)).first() is not None:
                        return "unchanged"
                    # registered before the records kept check values (r0002): add them
                    self._insert_checks(conn, old.id, rec, now)
                    return "updated"
            row = {
                "uid": rec.uid, "table_id": table_id, "kind": rec.kind, "title": rec.title,
                "run_dir": rec.run_dir, "run_path": rec.run_path, "host": rec.host,
                "procedure_name": rec.procedure_name,
                "procedure_sha256": rec.procedure_sha256, "stand_sha256": rec.stand_sha256,
                "result_sha256": rec.result_sha256, "created_utc": rec.created_utc,
                "started_utc": rec.started_utc, "completed_utc": rec.completed_utc,
                "registered_utc": now, "operator": rec.operator, "verdict": rec.verdict,
                "calibration_state": rec.calibration_state,
                "adjustment_note": rec.adjustment_note,
                "certificate_number": rec.certificate_number, "simulated": rec.simulated,
                "sessions": rec.sessions, "aborted": rec.aborted,
                "bench_version": rec.bench_version,
            }
            if old is None:
                run_id = conn.execute(sa.insert(s.runs).values(**row)
                                      .returning(s.runs.c.id)).scalar_one()
            else:
                run_id = old.id
                conn.execute(sa.update(s.runs).where(s.runs.c.id == run_id).values(**row))
                conn.execute(sa.delete(s.figures).where(s.figures.c.run_id == run_id))
                conn.execute(sa.delete(s.cert_files).where(s.cert_files.c.run_id == run_id))
                conn.execute(sa.delete(s.checks).where(s.checks.c.run_id == run_id))
            if rec.figures:
                conn.execute(sa.insert(s.figures), [
                    {"run_id": run_id, "axis": f.axis, "quantity": f.quantity,
                     "set_rate_dps": f.set_rate_dps, "value": f.value, "u": f.u,
                     "unit": f.unit, "tolerance": f.tolerance, "verdict": f.verdict,
                     "rule": f.rule} for f in rec.figures])
            if rec.cert_files:
                conn.execute(sa.insert(s.cert_files), [
                    {"run_id": run_id, "name": n, "sha256": h, "bytes": b}
                    for n, h, b in rec.cert_files])
            self._insert_checks(conn, run_id, rec, now)
            return "new" if old is None else "updated"

    def _insert_checks(self, conn: Connection, run_id: int, rec: RunRecord,
                       now: dt.datetime) -> None:
        ids: dict[str, int] = {}
        for c in rec.checks:
            if c.serial not in ids:
                ids[c.serial] = self._instrument_id(conn, c, now)
        if rec.checks:
            conn.execute(sa.insert(s.checks), [
                {"run_id": run_id, "instrument_id": ids[c.serial], "axis": c.axis,
                 "quantity": c.quantity, "set_rate_dps": c.set_rate_dps, "value": c.value,
                 "u": c.u, "unit": c.unit} for c in rec.checks])

    def _instrument_id(self, conn: Connection, c: CheckRecord, now: dt.datetime) -> int:
        i = s.instruments.c
        row = conn.execute(sa.select(i.id).where(i.serial == c.serial)).first()
        if row is None:   # a concurrent first registration: IntegrityError, retried whole
            return int(conn.execute(sa.insert(s.instruments).values(
                serial=c.serial, role=c.role, model=c.model, first_seen_utc=now,
                last_seen_utc=now).returning(i.id)).scalar_one())
        conn.execute(sa.update(s.instruments).where(i.id == row.id).values(
            last_seen_utc=now, **({"model": c.model} if c.model else {})))
        return int(row.id)

    def _table_id(self, conn: Connection, rec: RunRecord, interval_days: int | None,
                  now: dt.datetime) -> int:
        t = s.tables.c
        row = conn.execute(sa.select(t.id).where(t.serial == rec.serial)).first()
        values: dict[str, str | int | dt.datetime | None] = {
            "maker": rec.maker, "model": rec.model, "location": rec.location,
            "last_seen_utc": now}
        if interval_days or rec.interval_days:
            values["interval_days"] = interval_days or rec.interval_days
        if row is None:
            # a concurrent first registration of the same table raises IntegrityError
            # here; the whole transaction is retried and then finds the row
            return int(conn.execute(sa.insert(s.tables).values(
                serial=rec.serial, first_seen_utc=now, **values)
                .returning(t.id)).scalar_one())
        conn.execute(sa.update(s.tables).where(t.id == row.id).values(**values))
        return int(row.id)

    # -- the read API (issue 17's station view reads through these) -------------------------
    def tables(self) -> list[TableInfo]:
        """Every table recorded, by serial."""
        return self._tables(None)

    def table(self, serial: str) -> TableInfo | None:
        return next(iter(self._tables(serial)), None)

    def _tables(self, serial: str | None) -> list[TableInfo]:
        """Tables with their run counts and last dates, aggregated by the database (a lab
        holds years of runs: the due list must not read every run of every table)."""
        t, r = s.tables.c, s.runs.c
        date = sa.func.coalesce(r.completed_utc, r.started_utc, r.created_utc)
        stats = (sa.select(r.table_id, sa.func.count().label("n"),
                           sa.func.max(date).label("last"),
                           sa.func.max(sa.case((r.verdict == "pass", date))).label("passed"))
                 .group_by(r.table_id))
        one = [t.serial == serial] if serial is not None else []
        if serial is not None:
            stats = stats.join(s.tables, t.id == r.table_id).where(*one)
        stats_q = stats.subquery()
        # the certificate of each table's last run (the newest id among runs of that date)
        newest = (sa.select(sa.func.max(r.id)).join(
            stats_q, sa.and_(stats_q.c.table_id == r.table_id, date == stats_q.c.last))
            .group_by(r.table_id))
        with self.engine.connect() as conn:
            rows = conn.execute(sa.select(s.tables).where(*one).order_by(t.serial)).all()
            agg = {x.table_id: x for x in conn.execute(sa.select(stats_q))}
            certs = {x.table_id: x.certificate_number for x in conn.execute(
                sa.select(r.table_id, r.certificate_number).where(r.id.in_(newest)))}
        out = []
        for row in rows:
            a = agg.get(row.id)
            out.append(TableInfo(
                serial=row.serial, maker=row.maker, model=row.model, location=row.location,
                interval_days=row.interval_days, runs=int(a.n) if a else 0,
                last_run_utc=_utc(a.last) if a else None,
                last_pass_utc=_utc(a.passed) if a else None,
                last_certificate=certs.get(row.id)))
        return out

    def runs(self, serial: str) -> list[RunInfo]:
        """Every run of one table, oldest first (by the date the measurement ended)."""
        r, t = s.runs.c, s.tables.c
        with self.engine.connect() as conn:
            rows = conn.execute(sa.select(s.runs, t.serial).join(
                s.tables, r.table_id == t.id).where(t.serial == serial)).all()
            files: dict[int, dict[str, str]] = {}
            if rows:
                for f in conn.execute(sa.select(s.cert_files).where(
                        s.cert_files.c.run_id.in_([x.id for x in rows]))):
                    files.setdefault(f.run_id, {})[f.name] = f.sha256
        out = [RunInfo(
            id=x.id, uid=x.uid, serial=x.serial, kind=x.kind, title=x.title,
            run_dir=x.run_dir, run_path=x.run_path, host=x.host,
            procedure_name=x.procedure_name, procedure_sha256=x.procedure_sha256,
            date_utc=_utc(x.completed_utc or x.started_utc or x.created_utc),
            started_utc=_utc(x.started_utc), completed_utc=_utc(x.completed_utc),
            registered_utc=_utc(x.registered_utc) or dt.datetime.now(dt.UTC),
            operator=x.operator, verdict=x.verdict, calibration_state=x.calibration_state,
            adjustment_note=x.adjustment_note, certificate_number=x.certificate_number,
            simulated=bool(x.simulated), cert_files=files.get(x.id, {})) for x in rows]
        epoch = dt.datetime.min.replace(tzinfo=dt.UTC)
        return sorted(out, key=lambda x: (x.date_utc or epoch, x.id))

    def drafts(self, limit: int = 50, simulated: bool = False
               ) -> list[tuple[str, str, str, dt.datetime | None, str | None]]:
        """Runs that ended with a verdict (pass or fail) and hold no certificate number: drafts
        waiting for a signatory, newest first, as (serial, run_dir, verdict, date, operator).
        Runs on the twins (`simulated=True`) are listed apart: they describe no item."""
        r, t = s.runs.c, s.tables.c
        date = sa.func.coalesce(r.completed_utc, r.started_utc, r.created_utc)
        with self.engine.connect() as conn:
            rows = conn.execute(
                sa.select(t.serial, r.run_dir, r.verdict, date.label("date"), r.operator)
                .join(s.tables, r.table_id == t.id)
                .where(r.certificate_number.is_(None), r.verdict.in_(("pass", "fail")),
                       r.aborted.is_(False), r.simulated.is_(simulated))
                .order_by(date.desc(), r.id.desc()).limit(limit)).all()
        return [(x.serial, x.run_dir, x.verdict, _utc(x.date), x.operator) for x in rows]

    def run(self, uid: str) -> RunInfo | None:
        with self.engine.connect() as conn:
            serial = conn.execute(sa.select(s.tables.c.serial).join(
                s.runs, s.runs.c.table_id == s.tables.c.id)
                .where(s.runs.c.uid == uid)).scalar()
        if serial is None:
            return None
        return next((x for x in self.runs(serial) if x.uid == uid), None)

    def figures(self, run_uid: str) -> list[FigureRecord]:
        """Every figure of one run, as registered."""
        f, r = s.figures.c, s.runs.c
        with self.engine.connect() as conn:
            rows = conn.execute(sa.select(s.figures).join(s.runs, f.run_id == r.id)
                                .where(r.uid == run_uid).order_by(f.id)).all()
        return [_figure(x._mapping) for x in rows]

    def trend(self, serial: str, quantities: tuple[str, ...] | None = None,
              runs_of_table: list[RunInfo] | None = None) -> list[TrendPoint]:
        """Every figure of every run of one table, oldest run first (`runs_of_table`: its
        `runs(serial)` when the caller has them already)."""
        runs = {x.id: x for x in (runs_of_table if runs_of_table is not None
                                  else self.runs(serial))}
        if not runs:
            return []
        f = s.figures.c
        # plain tuples in FigureRecord's field order: years of runs are tens of thousands
        # of rows, and reading each field by name costs more than the query
        q = sa.select(f.run_id, f.axis, f.quantity, f.set_rate_dps, f.value, f.u, f.unit,
                      f.tolerance, f.verdict, f.rule).where(f.run_id.in_(list(runs)))
        if quantities:
            q = q.where(f.quantity.in_(quantities))
        by_run: dict[int, list[FigureRecord]] = {}
        with self.engine.connect() as conn:
            for run_id, *fields in conn.execute(q.order_by(f.id)).all():
                by_run.setdefault(run_id, []).append(FigureRecord(*fields))
        return [TrendPoint(r.uid, r.date_utc, r.certificate_number, r.calibration_state, fig)
                for rid, r in runs.items() for fig in by_run.get(rid, ())]

    # -- measurement assurance (control.py reads through these) ----------------------------
    def instruments(self) -> list[InstrumentInfo]:
        """Every instrument that has check values, by serial."""
        with self.engine.connect() as conn:
            rows = conn.execute(sa.select(s.instruments).order_by(
                s.instruments.c.serial)).all()
        return [InstrumentInfo(x.serial, x.role, x.model, _utc(x.first_seen_utc),
                               _utc(x.last_seen_utc)) for x in rows]

    def checks(self, serial: str) -> list[CheckPoint]:
        """Every check value of one instrument, oldest run first."""
        c, r, i, t = s.checks.c, s.runs.c, s.instruments.c, s.tables.c
        with self.engine.connect() as conn:
            rows = conn.execute(
                sa.select(s.checks, r.uid, r.run_dir, r.completed_utc, r.started_utc,
                          r.created_utc, r.simulated, t.serial.label("table_serial"))
                .join(s.runs, c.run_id == r.id).join(s.instruments, c.instrument_id == i.id)
                .join(s.tables, r.table_id == t.id)
                .where(i.serial == serial)).all()
        epoch = dt.datetime.min
        rows = sorted(rows, key=lambda x: (x.completed_utc or x.started_utc or x.created_utc
                                           or epoch, x.run_id, x.id))
        return [CheckPoint(
            run_uid=x.uid, run_dir=x.run_dir, table_serial=x.table_serial,
            date_utc=_utc(x.completed_utc or x.started_utc or x.created_utc),
            check=CheckRecord(serial, "", None, x.axis, x.quantity, x.set_rate_dps, x.value,
                              x.u, x.unit), simulated=bool(x.simulated)) for x in rows]

    def add_review(self, serial: str, reviewer: str, text: str, status: str | None,
                   through_utc: dt.datetime | None, host: str | None = None,
                   new_baseline: bool = False) -> ReviewInfo:
        """Journal a review of one instrument's control status (append-only)."""
        now = _now()
        through = through_utc.astimezone(dt.UTC).replace(tzinfo=None) \
            if through_utc is not None and through_utc.tzinfo else through_utc

        def write() -> None:
            with self._tx() as conn:
                iid = conn.execute(sa.select(s.instruments.c.id).where(
                    s.instruments.c.serial == serial)).scalar()
                if iid is None:
                    raise RecordsError(f"no instrument {serial!r} in {redact(self.url)}")
                conn.execute(sa.insert(s.reviews).values(
                    instrument_id=iid, utc=now, reviewer=reviewer, text=text, status=status,
                    through_utc=through, host=host, new_baseline=new_baseline))
        _retrying("review", write)
        return ReviewInfo(serial, _utc(now) or dt.datetime.now(dt.UTC), reviewer, text,
                          status, _utc(through), new_baseline)

    def reviews(self, serial: str) -> list[ReviewInfo]:
        """The review journal of one instrument, oldest first."""
        v, i = s.reviews.c, s.instruments.c
        with self.engine.connect() as conn:
            rows = conn.execute(sa.select(s.reviews).join(
                s.instruments, v.instrument_id == i.id).where(i.serial == serial)
                .order_by(v.utc, v.id)).all()
        return [ReviewInfo(serial, _utc(x.utc) or dt.datetime.now(dt.UTC), x.reviewer,
                           x.text, x.status, _utc(x.through_utc), bool(x.new_baseline))
                for x in rows]

    def due(self, today: dt.date | None = None, within_days: int = 30,
            intervals: Callable[[str, int | None], int | None] | None = None,
            everything: bool = False) -> list[DueItem]:
        """Tables due within `within_days` or overdue (all of them with `everything`).

        `intervals(serial, stand_days)` may override a table's interval (lab settings).
        A table with no interval from anywhere has no due date and is not listed.
        """
        today = today or dt.datetime.now(dt.UTC).date()
        out = []
        for t in self.tables():
            days = intervals(t.serial, t.interval_days) if intervals else t.interval_days
            if not days:
                continue
            if t.last_pass_utc is None:
                item = DueItem(t, None, None)
            else:
                due = t.last_pass_utc.date() + dt.timedelta(days=days)
                item = DueItem(t, due, (due - today).days)
            if everything or item.days_left is None or item.days_left <= within_days:
                out.append(item)
        return sorted(out, key=lambda d: (d.days_left if d.days_left is not None else -10**9,
                                          d.table.serial))


def _figure(x: RowMapping) -> FigureRecord:
    return FigureRecord(axis=x["axis"], quantity=x["quantity"],
                        set_rate_dps=x["set_rate_dps"], value=x["value"], u=x["u"],
                        unit=x["unit"], tolerance=x["tolerance"], verdict=x["verdict"],
                        rule=x["rule"])


def _short(e: BaseException) -> str:
    """The reason in words (bench.app.db.reason_in_words), not the driver's exception."""
    return reason_in_words(e)
