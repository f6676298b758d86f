"""The lab register (docs/register.md): accounts, the equipment inventory, certificate
numbers and issued revisions, and the audit trail, in one database the lab controls.

One class for SQLite (a single bench; guards against mistakes) and PostgreSQL (a lab
server; the server enforces who may change what: bench/app/register/pgsql.py). Every
change is one transaction that also appends its audit entry, so an action and its record
stand or fall together.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable, Mapping, Sequence

import sqlalchemy as sa
from sqlalchemy.engine import Connection
from sqlalchemy.exc import DBAPIError

from bench.app.db import make_engine
from bench.app.register import schema as s
from bench.app.register import wire
from bench.app.register.equipment import RegisterEquipment
from bench.app.register.model import (
    ACTING_VIA,
    ISSUER_KEYS,
    MEANING_ISSUE,
    MIGRATIONS,
    MIN_PASSWORD_CHARS,
    SETTING_DEFAULTS,
    SIGNING_SETTING,
    Account,
    AuditDetail,
    AuthError,
    Calibration,
    Deviation,
    Equipment,
    IssueArgs,
    ItemRow,
    Receipt,
    RegisterError,
    Revision,
    RunEvent,
    RunRecord,
    _account,
    _now_utc,
    _revision,
    _sqlite_file,
    _with_via,
    hash_password,
    password_problem,
    redact,
)
from bench.core import rundir_layout as layout

__all__ = ["ACTING_VIA", "ISSUER_KEYS", "MEANING_ISSUE", "MIGRATIONS", "MIN_PASSWORD_CHARS",
           "REMOTE_OPENERS", "SETTING_DEFAULTS", "SIGNING_SETTING", "Account", "AuthError",
           "Calibration", "Deviation", "Equipment", "IssueArgs", "Receipt", "Register",
           "RegisterError", "Revision", "RunEvent", "RunRecord", "hash_password",
           "password_problem", "redact"]

#: how a register reached over the network opens, by URL scheme: client.py adds itself
#: (the package imports it), so this module imports no client
REMOTE_OPENERS: dict[str, Callable[[str], Register]] = {}


class Register(RegisterEquipment):
    """One connection pool to one register; `open` migrates it to the newest schema.

    A chain of classes, bottom up: trail.py (the database, the audit trail, the
    settings), accounts.py, equipment.py, and here the runs, the certificate numbers and
    their issued revisions."""

    @classmethod
    def open(cls, url: str, migrate: bool = True, create: bool | None = None) -> Register:
        """The register at `url`: a database (sqlite:///, postgresql://) or the lab's
        register service (http(s)://, bench/app/register/client.py). Only `migrate=True`
        (init, an owner's command) may create an SQLite file: a command that reads a
        register never makes an empty one (issue 56)."""
        scheme = url.split("://", 1)[0]
        if scheme in ("http", "https"):
            return REMOTE_OPENERS[scheme](url)
        _sqlite_file(url, create=migrate if create is None else create)
        try:
            reg = cls(url, make_engine(url))
            if migrate:
                reg._migrate()
            else:
                with reg.engine.connect() as c:
                    c.execute(sa.select(s.accounts.c.name).limit(1))
        except DBAPIError as e:
            raise RegisterError(f"register {redact(url)}: cannot be used: "
                                f"{str(e.orig).strip().splitlines()[0]}") from e
        return reg

    def __enter__(self) -> Register:
        return self

    remote = False

    def allocate(self, run_uid: str, prefix: str, actor: str) -> str:
        """The run's certificate number: allocated once per run, by the register alone."""
        with self._tx() as conn:
            if self.pg:
                return str(conn.execute(sa.text("SELECT reg_allocate(:u, :p, :a)"),
                                        {"u": run_uid, "p": prefix, "a": actor}).scalar())
            num = conn.execute(sa.select(s.certificates.c.number)
                               .where(s.certificates.c.run_uid == run_uid)).scalar()
            if num is not None:
                return str(num)
            seq = int(conn.execute(sa.select(sa.func.coalesce(sa.func.max(
                s.certificates.c.seq), 0))).scalar() or 0) + 1
            utc = _now_utc()
            num = f"{prefix}-{utc[:4]}-{seq:05d}"
            conn.execute(s.certificates.insert().values(number=num, seq=seq, run_uid=run_uid,
                                                        allocated_utc=utc[:19] + "Z"))
            self._append(conn, actor, "number allocated", num, f"run {run_uid}")
            return num

    def number_of_run(self, run_uid: str) -> str | None:
        with self.engine.connect() as c:
            return c.execute(sa.select(s.certificates.c.number)
                             .where(s.certificates.c.run_uid == run_uid)).scalar()

    def revisions(self, number: str) -> list[Revision]:
        with self.engine.connect() as c:
            return [_revision(r._mapping) for r in c.execute(
                sa.select(s.revisions).where(s.revisions.c.number == number)
                .order_by(s.revisions.c.revision))]

    def find_revision(self, sha256: str) -> Revision | None:
        """The revision whose PDF, DCC, HTML or result.json has this digest."""
        rv = s.revisions.c
        with self.engine.connect() as c:
            r = c.execute(sa.select(s.revisions).where(sa.or_(
                rv.pdf_sha256 == sha256, rv.dcc_sha256 == sha256, rv.html_sha256 == sha256,
                rv.result_sha256 == sha256))).first()
        return None if r is None else _revision(r._mapping)

    def register_run(self, uid: str, bench: str, performer: str | None, version: str,
                     simulated: bool, inputs: Mapping[str, str],
                     items: Sequence[ItemRow]) -> RunRecord:
        """A run at its start, before anything moves: its uid (never a folder name), the
        bench, the authenticated performer, the version, the inputs' digests and the
        stand's items. A uid is registered once; a resume is `run_session`."""
        via = ACTING_VIA.get() or f"bench {bench}"
        utc = _now_utc()
        with self._tx() as conn:
            if conn.execute(sa.select(s.runs.c.uid).where(s.runs.c.uid == uid)).first():
                raise RegisterError(f"run {uid} is registered already (a resume registers a "
                                    "session of it)")
            conn.execute(s.runs.insert().values(
                uid=uid, bench=bench, performer=performer, version=version,
                simulated=simulated, inputs=wire.dump_sorted(dict(inputs)),
                items=wire.dump_sorted([dict(i) for i in items]),
                registered_utc=utc, via=via, raw="{}"))
            conn.execute(s.run_events.insert().values(uid=uid, utc=utc, kind="start",
                                                      detail=wire.dump_event({"via": via})))
            self._append(conn, performer or f"bench {bench}", "run registered", uid,
                         {"bench": bench, "performer": performer, "version": version,
                          "simulated": simulated, "inputs": dict(inputs)})
        return self._run_record(uid)

    def run_session(self, uid: str, session: int, performer: str | None) -> None:
        """A resume of a registered run: one more session of the same uid."""
        with self._tx() as conn:
            self._known_run(conn, uid)
            detail = {"session": session, "performer": performer,
                      "via": ACTING_VIA.get() or "this bench"}
            conn.execute(s.run_events.insert().values(uid=uid, utc=_now_utc(), kind="resume",
                                                      detail=wire.dump_event(detail)))
            self._append(conn, performer or "bench", "run resumed", uid, detail)

    def deliver_result(self, uid: str, kind: str, result: bytes, raw: Mapping[str, str],
                       reason: str | None = None) -> RunRecord:
        """A session's end or an analysis: result.json's bytes and each raw capture's
        digest. A raw capture the register has seen never changes (refused, named)."""
        import hashlib

        if kind not in ("session", "analysis"):
            raise RegisterError(f"a run's result comes from a session or an analysis, not "
                                f"{kind!r}")
        digest = hashlib.sha256(result).hexdigest()
        try:
            text = result.decode("utf-8")
        except UnicodeDecodeError:
            raise RegisterError("result.json is not UTF-8 text") from None
        utc = _now_utc()
        with self._tx() as conn:
            bench, held = self._known_run(conn, uid)
            seen = wire.digests(held, "raw")
            changed = sorted(k for k, v in raw.items() if k in seen and seen[k] != v)
            gone = sorted(k for k in seen if k not in raw)
            if changed or gone:
                raise RegisterError(f"run {uid}: " + "; ".join(
                    [f"raw capture {k} changed since the register saw it" for k in changed]
                    + [f"raw capture {k} is missing (the register saw it)" for k in gone]))
            conn.execute(s.runs.update().where(s.runs.c.uid == uid).values(
                result_sha256=digest, result=text, result_utc=utc,
                raw=wire.dump_sorted({**seen, **raw})))
            detail: AuditDetail = {"result_sha256": digest, "raw_captures": len(raw),
                                   "reason": reason, "via": ACTING_VIA.get() or "this bench"}
            conn.execute(s.run_events.insert().values(uid=uid, utc=utc, kind=kind,
                                                      detail=wire.dump_event(detail)))
            self._append(conn, f"bench {bench}", f"run {kind} result", uid, detail)
        return self._run_record(uid)

    def run_record(self, uid: str) -> RunRecord | None:
        with self.engine.connect() as c:
            r = c.execute(sa.select(s.runs).where(s.runs.c.uid == uid)).first()
            if r is None:
                return None
            events = tuple(wire.event(e.utc, e.kind, e.detail) for e in c.execute(
                sa.select(s.run_events).where(s.run_events.c.uid == uid)
                .order_by(s.run_events.c.id)))
        return RunRecord(r.uid, r.bench, r.performer, r.version, bool(r.simulated),
                         wire.digests(r.inputs, "inputs"), wire.items(r.items), r.registered_utc,
                         r.via, r.result_sha256, r.result, r.result_utc, wire.digests(r.raw, "raw"),
                         events)

    def runs_using(self, serial: str) -> list[RunRecord]:
        """Every run whose record of its start names the item `serial` among the stand's
        items (issue 58: what a finding on the item touches), oldest first."""
        with self.engine.connect() as c:
            rows = c.execute(sa.select(s.runs).order_by(s.runs.c.registered_utc,
                                                        s.runs.c.uid)).all()
        uids = [r.uid for r in rows
                if any(i.get("serial") == serial for i in wire.items(r.items))]
        return [self._run_record(u) for u in uids]

    def impact_assessed(self, by: Account, serial: str, detail: AuditDetail) -> str:
        """The audit entry of an impact assessment (issue 58; ISO/IEC 17025 7.10,
        nonconforming work): the item, the finding, the runs and certificates it touched.
        A quality account's act; returns the entry's digest."""
        if not by.has("quality"):
            raise AuthError(f"{by.name} does not hold the quality role: only quality "
                            "records an impact assessment")
        if not next(iter(self.equipment(serial)), None):
            raise RegisterError(f"equipment {serial!r} is not in the inventory")
        with self._tx() as conn:
            return self._append(conn, by.name, "impact assessed", serial, dict(detail))

    def _run_record(self, uid: str) -> RunRecord:
        rec = self.run_record(uid)
        assert rec is not None, uid     # written in this register a moment ago
        return rec

    def _known_run(self, conn: Connection, uid: str) -> tuple[str, str]:
        """The registered run's bench and raw captures' digests (its JSON column)."""
        row = conn.execute(sa.select(s.runs.c.bench, s.runs.c.raw)
                           .where(s.runs.c.uid == uid)).first()
        if row is None:
            raise RegisterError(f"run {uid} was not registered at its start")
        return row.bench, row.raw

    def dcc_signer(self, signatory: Account) -> Callable[[bytes], bytes] | None:
        """Who signs an issued DCC for this register: on one bench the lab file's key,
        when the register designates its certificate (authorise.designated_signing);
        the register service signs with its own key (client.py)."""
        return None

    def withdraw(self, by: Account, number: str, reason: str) -> Revision:
        """Withdraw a certificate's current revision without a replacement (ISO/IEC 17025
        7.8.8): a quality or signatory account, with the reason in a sentence."""
        if not (by.has("quality") or by.has("signatory")):
            raise AuthError(f"{by.name} holds neither the quality nor the signatory role")
        why = reason.strip()
        if len(why) < 20 or len(why.split()) < 4:
            raise RegisterError("a withdrawal states its reason in a sentence (at least four "
                                "words)")
        rv = s.revisions.c
        with self._tx() as conn:
            current = conn.execute(sa.select(s.revisions).where(rv.number == number)
                                   .where(rv.withdrawn_utc.is_(None))
                                   .order_by(rv.revision.desc())).first()
            if current is None:
                known = conn.execute(sa.select(rv.revision).where(rv.number == number)).first()
                raise RegisterError(f"certificate {number}: " + (
                    "every revision is withdrawn already" if known else
                    "no issued revision in this register"))
            conn.execute(s.revisions.update().where(rv.id == current.id).values(
                withdrawn_utc=_now_utc()[:19] + "Z", withdrawn_reason=why,
                withdrawn_by=by.name))
            self._append(conn, by.name, "withdrawn", f"{number} revision {current.revision}",
                         {"reason": why})
        return next(r for r in self.revisions(number) if r.revision == current.revision)

    def begin_issue(self, signatory: Account, number: str, revision: int = 0,
                    result_sha256: str = "") -> Receipt:
        """The issue's first audit entry, written before anything is rendered (number,
        revision, signatory, the register's time, the result's digest): each issued
        document states its sequence number and digest, so a trail truncated or rewritten
        later no longer holds what customers hold (issue 54). Its time, by the register's
        clock, is the issue's: printed and recorded (the client's clock is never stored)."""
        if not signatory.has("signatory"):
            raise AuthError(f"{signatory.name} is not an active signatory")
        utc = dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
        with self._tx() as conn:
            digest = self._append(conn, signatory.name, "issue begun",
                                  f"{number} revision {revision}",
                                  {"issued_utc": utc, "result_sha256": result_sha256})
            seq = int(conn.execute(sa.select(s.audit.c.seq)
                                   .where(s.audit.c.digest == digest)).scalar_one())
        receipt = Receipt(utc, seq, digest)
        self._pending[(signatory.name, number)] = utc
        return receipt

    def issue(self, number: str, revision: int, signatory: Account,
              digests: Mapping[str, str], reason: str | None,
              detail: AuditDetail) -> Revision:
        """Record an issued revision (and the withdrawal of the one before), checked by the
        register under its lock: the next revision, an active signatory, a reason for a
        re-issue. The time is the one `begin_issue` gave (else now), the meaning the
        register's own. Raises RegisterError when refused."""
        issued_utc = self._pending.pop((signatory.name, number), None) or \
            dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
        args: IssueArgs = {"n": number, "r": revision, "s": signatory.name, "m": MEANING_ISSUE,
                "why": reason or "", "t": issued_utc, "res": digests[layout.RESULT],
                "pdf": digests[layout.CERTIFICATE_PDF], "dcc": digests[layout.CERTIFICATE_DCC],
                "html": digests[layout.CERTIFICATE_HTML],
                "d": _with_via(detail)}
        with self._tx() as conn:
            if self.pg:
                conn.execute(sa.text("SELECT reg_issue(:n, :r, :s, :m, :why, :t, :res, :pdf, "
                                     ":dcc, :html, :d)"), args)
            else:
                self._issue_sqlite(conn, args)
        return next(r for r in self.revisions(number) if r.revision == revision)

    def _issue_sqlite(self, conn: Connection, a: IssueArgs) -> None:
        """pgsql.ISSUE, step for step, for a register in one SQLite file."""
        r = conn.execute(sa.select(s.accounts).where(s.accounts.c.name == a["s"])).first()
        if r is None or not _account(r._mapping).has("signatory"):
            raise RegisterError(f"register: {a['s']} is not an active signatory account")
        if conn.execute(sa.select(s.certificates.c.number)
                        .where(s.certificates.c.number == a["n"])).first() is None:
            raise RegisterError(f"register: certificate number {a['n']} was not allocated "
                                "by this register")
        last = int(conn.execute(sa.select(sa.func.coalesce(sa.func.max(s.revisions.c.revision),
                                                           0))
                                .where(s.revisions.c.number == a["n"])).scalar() or 0)
        if a["r"] != last + 1:
            raise RegisterError(f"register: {a['n']} revision {a['r']} is not the next "
                                f"(revision {last} is the last issued)")
        if last and not a["why"].strip():
            raise RegisterError(f"register: a re-issue of {a['n']} needs a reason")
        conn.execute(s.revisions.update().where(s.revisions.c.number == a["n"])
                     .where(s.revisions.c.withdrawn_utc.is_(None)).values(withdrawn_utc=a["t"]))
        d = self._append_text(conn, a["s"], "issue" if not last else "re-issue",
                              f"{a['n']} revision {a['r']}", a["d"])
        conn.execute(s.revisions.insert().values(
            number=a["n"], revision=a["r"], issued_utc=a["t"], signatory=a["s"],
            signatory_name=r.full_name, meaning=a["m"], reason=a["why"].strip() or None,
            result_sha256=a["res"], pdf_sha256=a["pdf"], dcc_sha256=a["dcc"],
            html_sha256=a["html"], audit_digest=d))
