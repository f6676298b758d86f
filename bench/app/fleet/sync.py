"""Delivering a bench's run directories to the lab database (PostgreSQL).

One delivery of one run, in transactions of at most `BATCH_LINES` event lines: the bench
and the run are upserted by name and uid, the new event lines inserted under (run, line
number) with ON CONFLICT DO NOTHING, the run's high-water mark and health updated, and
a notification sent on `CHANNEL` (PostgreSQL delivers it at commit, so the station never
hears of rows it cannot read yet). The outbox's cursor is written after each commit. Then
result.json, once written, is stored with the run and the run registered in the records
(`Records.register`, idempotent). So a delivery can be repeated at any moment (after an
outage, a kill between two batches, a server restart) and the database ends with each
line once.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import socket
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import msgspec
import sqlalchemy as sa
from sqlalchemy.dialects.postgresql import insert as pg_insert
from sqlalchemy.engine import Connection
from sqlalchemy.sql.elements import ColumnElement

from bench.app.db import away_text, redact
from bench.app.fleet import CHANNEL
from bench.app.fleet.codec import JournalLine, read_result
from bench.app.fleet.health import HealthSample
from bench.app.fleet.journal import new_lines
from bench.app.fleet.outbox import Outbox
from bench.app.records import schema as s
from bench.app.records.extract import NotARun, record_of, run_uid
from bench.app.records.store import Records, RecordsError
from bench.core import rundir_layout as layout
from bench.core.journal_codec import RunMeta, read_meta
from bench.core.yamlfile import read_mapping

#: event lines per transaction: a long log after a long outage goes in bounded pieces,
#: each committed (and its cursor written) before the next
BATCH_LINES = 500
POSTGRES = ("postgresql://", "postgres://", "postgresql+psycopg://")
Intervals = Callable[[str, int | None], int | None]


class SyncError(RuntimeError):
    """A delivery could not be made; the message names the database and the reason."""


def is_lab_server(url: str | None) -> bool:
    """The lab's delivery goes to PostgreSQL only (LISTEN/NOTIFY; a bench's SQLite file
    is its own records, not a lab server)."""
    return bool(url) and str(url).startswith(POSTGRES)


def bench_name(run_path: Path, stated: str | None = None) -> str:
    """The bench's name: stated (the stand file's `bench.name` as parsed), else the run's
    copy of its stand file, else this machine's host name."""
    if stated:
        return stated
    stand = read_mapping(run_path / layout.STAND)
    block = stand.get("bench") if isinstance(stand, dict) else None
    name = block.get("name") if isinstance(block, dict) else None
    return str(name) if name else socket.gethostname()


def _naive_utc(stamp: str | None) -> dt.datetime | None:
    if not stamp:
        return None
    try:
        t = dt.datetime.fromisoformat(stamp)
    except ValueError:
        return None
    return t.astimezone(dt.UTC).replace(tzinfo=None) if t.tzinfo else t


@dataclass(frozen=True)
class RunFacts:
    """What the station lists a run by, read from its directory's files."""

    uid: str
    run_dir: str
    title: str | None
    kind: str | None
    serial: str | None
    maker: str | None
    model: str | None
    simulated: bool
    created_utc: dt.datetime | None

    @classmethod
    def of(cls, run_path: Path) -> RunFacts:
        try:
            meta = read_meta(run_path / layout.META)
        except (OSError, ValueError):
            meta = RunMeta()
        stand = read_mapping(run_path / layout.STAND)
        stand = stand if isinstance(stand, dict) else {}
        proc = read_mapping(run_path / layout.PROCEDURE)
        proc = proc if isinstance(proc, dict) else {}
        block = stand.get("stand")
        ident: dict[str, str | int | float | None] = block if isinstance(block, dict) else {}
        return cls(uid=run_uid(meta, run_path.name), run_dir=run_path.name,
                   title=str(proc.get("title") or run_path.name),
                   kind=str(proc["procedure"]) if proc.get("procedure") else None,
                   serial=str(ident["serial"]) if ident.get("serial") else None,
                   maker=str(ident["maker"]) if ident.get("maker") else None,
                   model=str(ident["model"]) if ident.get("model") else None,
                   simulated="sim" in stand,
                   created_utc=_naive_utc(meta.get("created_utc")))


@dataclass(frozen=True)
class Delivery:
    """What one delivery of one run added to the lab database."""

    run: str
    lines: int            # event lines sent
    events: int           # event rows the database did not have yet
    result: bool          # result.json stored (new or changed)
    registered: str | None   # the records' answer ('new', 'updated', 'unchanged'), or None


def _sha256(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


class LabLink:
    """A bench's connection to the lab database (the records' engine, migrated once)."""

    def __init__(self, url: str, interval_for: Intervals | None = None) -> None:
        """`interval_for(serial, stand_days)`: the recertification interval a registration
        records (the lab settings' override, `RecordsTarget.interval_for`), as
        `bench run` and `bench records import` register it."""
        if not is_lab_server(url):
            raise SyncError(f"{redact(url)}: the lab database is a PostgreSQL URL "
                            "(postgresql://ROLE@HOST/DB)")
        self.url = url
        self.interval_for = interval_for
        self._records: Records | None = None
        #: each run's facts, read once (its input files do not change while it runs)
        self._facts: dict[Path, RunFacts] = {}

    def records(self) -> Records:
        if self._records is None:
            try:
                self._records = Records.open(self.url)
            except RecordsError as e:
                raise SyncError(away_text(self.url, e.__cause__ or e)) from e
        return self._records

    def close(self) -> None:
        if self._records is not None:
            self._records.close()
            self._records = None

    def __enter__(self) -> LabLink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def deliver(self, run_path: Path, outbox: Outbox, bench: str,
                health: HealthSample | None = None, register: bool = True,
                batch_lines: int = BATCH_LINES) -> Delivery:
        """Bring the lab database up to date with one run directory; repeatable at will.

        `register`: also register result.json in the records (at a run's end and in
        `bench records sync`; the background delivery of a running run leaves it)."""
        try:
            return self._deliver(run_path, outbox, bench, health, register, batch_lines)
        except SyncError:
            raise
        except Exception as e:  # noqa: BLE001 - a lost server, a refused role: say which
            self.close()       # a fresh connection next time (a restarted server)
            raise SyncError(away_text(self.url, e)) from e

    def _deliver(self, run_path: Path, outbox: Outbox, bench: str,
                 health: HealthSample | None, register: bool, batch_lines: int) -> Delivery:
        rec = self.records()
        facts = self._facts.get(run_path)
        if facts is None:
            facts = self._facts[run_path] = RunFacts.of(run_path)
        cur = outbox.cursor(run_path.name)
        sent = added = 0
        first = True
        while True:
            lines, offset, seq = new_lines(run_path, cur.offset_bytes, cur.seq, batch_lines)
            # a run the database has not seen yet, or a health sample, is sent even
            # without new lines; an up-to-date run costs no round trip
            if lines or (first and (health is not None or cur.offset_bytes == 0)):
                with rec.engine.begin() as conn:
                    added += self._batch(conn, bench, facts, lines, health)
                cur = msgspec.structs.replace(cur, offset_bytes=offset, seq=seq)
                outbox.save(run_path.name, cur)
                sent += len(lines)
            first = False
            if len(lines) < batch_lines:
                break
        stored = False
        result_path = run_path / layout.RESULT
        sha = _sha256(result_path)
        if sha is not None and sha != cur.result_sha256:
            try:
                result = read_result(result_path)
            except ValueError:
                result = None          # being replaced right now: the next delivery
            if result is not None:
                with rec.engine.begin() as conn:
                    run_id = self._run_id(conn, self._bench_id(conn, bench), facts)
                    conn.execute(sa.update(s.bench_runs).where(s.bench_runs.c.id == run_id)
                                 .values(result=result.document, result_sha256=sha,
                                         verdict=(result.verdict or "")[:20] or None))
                    self._notify(conn, bench, facts.uid, cur.seq)
                cur = msgspec.structs.replace(cur, result_sha256=sha)
                outbox.save(run_path.name, cur)
                stored = True
        registered = None
        if register and sha is not None and sha == cur.result_sha256 \
                and sha != cur.registered_sha256:
            try:
                record = record_of(run_path)
            except NotARun:
                record = None          # incomplete: nothing for the records (yet)
            if record is not None:
                days = (self.interval_for(record.serial, record.interval_days)
                        if self.interval_for else record.interval_days)
                registered = rec.register(record, days)
                cur = msgspec.structs.replace(cur, registered_sha256=sha)
                outbox.save(run_path.name, cur)
        return Delivery(run_path.name, sent, added, stored, registered)

    # -- one transaction ------------------------------------------------------------------
    @staticmethod
    def _now() -> ColumnElement[dt.datetime]:
        """The lab server's clock, UTC: every age the station shows is on one clock."""
        return sa.func.timezone("UTC", sa.func.now())

    def _bench_id(self, conn: Connection, bench: str) -> int:
        b = s.benches
        q = pg_insert(b).values(name=bench, host=socket.gethostname(),
                                first_seen_utc=self._now(), last_seen_utc=self._now())
        q = q.on_conflict_do_update(index_elements=[b.c.name],
                                    set_={"last_seen_utc": self._now(),
                                          "host": q.excluded.host})
        return int(conn.execute(q.returning(b.c.id)).scalar_one())

    def _run_id(self, conn: Connection, bench_id: int, facts: RunFacts) -> int:
        r = s.bench_runs
        values = {"title": facts.title, "kind": facts.kind, "serial": facts.serial,
                  "maker": facts.maker, "model": facts.model, "simulated": facts.simulated,
                  "created_utc": facts.created_utc, "run_dir": facts.run_dir}
        q = pg_insert(r).values(bench_id=bench_id, uid=facts.uid, last_seq=0,
                                received_utc=self._now(), **values)
        q = q.on_conflict_do_update(constraint="uq_bench_runs_bench_uid",
                                    set_={**values, "received_utc": self._now()})
        return int(conn.execute(q.returning(r.c.id)).scalar_one())

    def _batch(self, conn: Connection, bench: str, facts: RunFacts, lines: list[JournalLine],
               health: HealthSample | None) -> int:
        run_id = self._run_id(conn, self._bench_id(conn, bench), facts)
        rows = [{"run_id": run_id, "seq": x.seq, "utc": _naive_utc(x.utc),
                 "event": x.name[:60], "body": x.body}
                for x in lines if x.body is not None]
        added = 0
        if rows:
            # RETURNING lists the rows inserted, not those the key refused
            added = len(conn.execute(pg_insert(s.bench_events).values(rows)
                                     .on_conflict_do_nothing()
                                     .returning(s.bench_events.c.seq)).all())
        r = s.bench_runs.c
        values: dict[str, object] = {}
        if lines:
            values["last_seq"] = sa.func.greatest(r.last_seq, lines[-1].seq)
        stamps = [t for t in (_naive_utc(x.utc) for x in lines) if t is not None]
        if stamps:
            values["last_event_utc"] = sa.func.greatest(r.last_event_utc, max(stamps))
        if health is not None:
            values["health"] = health
            values["health_utc"] = _naive_utc(health.get("sampled_utc"))
        if values:
            conn.execute(sa.update(s.bench_runs).where(r.id == run_id).values(**values))
        self._notify(conn, bench, facts.uid, lines[-1].seq if lines else None)
        return int(added)

    @staticmethod
    def _notify(conn: Connection, bench: str, uid: str, seq: int | None) -> None:
        payload = json.dumps({"bench": bench, "uid": uid, "seq": seq})
        conn.execute(sa.select(sa.func.pg_notify(CHANNEL, payload)))


def run_dirs(runs_dir: Path) -> list[Path]:
    """The run directories directly in a runs folder (those with an event log), by name."""
    try:
        return sorted(p for p in Path(runs_dir).iterdir() if (p / layout.EVENTS).is_file())
    except FileNotFoundError:
        return []


def sync_folder(runs_dir: Path, url: str, bench: str | None = None,
                batch_lines: int = BATCH_LINES, interval_for: Intervals | None = None,
                only: list[Path] | None = None) -> list[Delivery]:
    """`bench records sync`: deliver every run of a runs folder (or `only` those of
    them) (idempotent)."""
    outbox = Outbox(runs_dir, url)
    out = []
    with LabLink(url, interval_for) as link:
        for path in run_dirs(runs_dir) if only is None else only:
            out.append(link.deliver(path, outbox, bench_name(path, bench),
                                    batch_lines=batch_lines))
    return out
