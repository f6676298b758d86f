"""The lab register (docs/register.md): accounts, the equipment inventory, certificate
numbers and issued revisions, and the audit trail, in one database the lab controls.

One class for SQLite (a single bench; guards against mistakes) and PostgreSQL (a lab
server; the server enforces who may change what: bench/app/register/pgsql.py). Every
change is one transaction that also appends its audit entry, so an action and its record
stand or fall together.
"""

from __future__ import annotations

import contextvars
import datetime as dt
import getpass
import json
import os
import re
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, TypedDict

import sqlalchemy as sa
from sqlalchemy.engine import Connection, Engine, RowMapping
from sqlalchemy.exc import DBAPIError, IntegrityError

from bench.app.db import make_engine, upgrade_to_head
from bench.app.names import ROLES
from bench.app.register import chain
from bench.app.register import schema as s
from bench.core import rundir_layout as layout

if TYPE_CHECKING:   # argon2 is imported when a password is checked
    from argon2 import PasswordHasher

MIGRATIONS = Path(__file__).resolve().parent / "migrations"
MEANING_ISSUE = "authorised for issue"
#: the register's setting naming the DCC signing certificate (SHA-256 of its PEM file)
SIGNING_SETTING = "dcc_signing_certificate_sha256"

#: the register's settings an admin changes (`bench register settings set`, audited), with
#: their defaults: guessing is limited where the password is checked (issue 53)
SETTING_DEFAULTS: dict[str, int] = {
    "lockout_attempts": 5,          # failed attempts on one account within the window ...
    "lockout_window_s": 15 * 60,    # ... lock it
    "lockout_s": 15 * 60,           # for this long, even against the right password
    "password_max_age_days": 180,   # then the password must be changed
    "deviation_max_days": 30,       # a deviation expires at most this long after it is made
}

#: the issuer's identity as the register holds it (issue 54): printed on every issued
#: certificate and DCC from here, never from a file the operator edits
ISSUER_KEYS = ("issuer.name", "issuer.address", "issuer.code", "issuer.accreditation",
               "issuer.prefix")

#: who the person acts through ("bench hall-1 at 127.0.0.1"): the register service sets
#: it for the request it serves, and every audit entry written meanwhile names it
ACTING_VIA: contextvars.ContextVar[str | None] = contextvars.ContextVar("acting_via",
                                                                         default=None)


@dataclass(frozen=True)
class Receipt:
    """An issue's first audit entry as the issued documents state it."""

    issued_utc: str
    audit_seq: int
    audit_digest: str


class IssueArgs(TypedDict):
    """The parameters of pgsql.ISSUE (`reg_issue`), by their bind names."""

    n: str          # certificate number
    r: int          # revision
    s: str          # signatory account
    m: str          # meaning of the signature
    why: str        # reason of a re-issue ("" for revision 1)
    t: str          # issued, UTC
    res: str        # SHA-256 of result.json, the PDF, the DCC, the HTML
    pdf: str
    dcc: str
    html: str
    d: str          # detail, JSON


#: how a register reached over the network opens, by URL scheme: client.py adds itself
#: (the package imports it), so this module imports no client
REMOTE_OPENERS: dict[str, Callable[[str], Register]] = {}


class RegisterError(RuntimeError):
    """The register cannot be reached or used, or refused the action; the message says
    which and why."""


class AuthError(RegisterError):
    """Name and password do not identify an active account holding the role."""


def _now_utc() -> str:
    return dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def _os_user() -> str:
    try:
        return getpass.getuser()
    except (KeyError, OSError):
        return "unknown"


def _hasher() -> PasswordHasher:
    from argon2 import PasswordHasher  # argon2id with the library's RFC 9106 defaults

    return PasswordHasher()


#: issue 53's password rules (NIST SP 800-63B 5.1.1.2: length, and not a known password)
MIN_PASSWORD_CHARS = 12


def password_problem(name: str, password: str) -> str | None:
    """Why `password` may not be the password of account `name` (None: it may)."""
    if len(password) < MIN_PASSWORD_CHARS:
        return f"a password has at least {MIN_PASSWORD_CHARS} characters"
    low = password.casefold()
    if name and name.casefold() in low:
        return "a password does not contain the account's name"
    if low in _common_passwords():
        return ("a password is not one of the 30,000 most common passwords "
                "(zxcvbn's list)")
    return None


def _common_passwords() -> frozenset[str]:
    from zxcvbn.frequency_lists import FREQUENCY_LISTS  # a well-kept list (Dropbox's)

    if not _COMMON:
        _COMMON.append(frozenset(p.casefold() for p in FREQUENCY_LISTS["passwords"]))
    return _COMMON[0]


_COMMON: list[frozenset[str]] = []


def hash_password(password: str, name: str = "") -> str:
    why = password_problem(name, password)
    if why:
        raise RegisterError(why)
    return str(_hasher().hash(password))


def _verify(stored: str, password: str) -> bool:
    from argon2.exceptions import InvalidHashError, VerificationError

    try:
        return bool(_hasher().verify(stored, password))
    except (VerificationError, InvalidHashError):
        return False


@dataclass(frozen=True)
class Account:
    name: str
    full_name: str
    roles: tuple[str, ...]
    function: str | None
    active: bool
    must_change: bool = False
    password_changed_utc: str | None = None

    def has(self, role: str) -> bool:
        return self.active and role in self.roles


@dataclass(frozen=True)
class Deviation:
    reason: str
    expires: dt.date
    recorded_by: str
    recorded_utc: str
    revoked_utc: str | None = None
    revoked_by: str | None = None

    def covers(self, day: dt.date) -> bool:
        return self.revoked_utc is None and self.expires >= day


@dataclass(frozen=True)
class Calibration:
    """One calibration of an item (ISO/IEC 17025 6.4.13 e): in force from `calibrated_on`
    until the next one; `found` and `found_error` are how it was found before adjustment."""

    certificate: str
    issuer: str
    calibrated_on: dt.date | None       # None: not stated (an item's first record, in force
    due: dt.date                        # from before the inventory knew it)
    found: str | None = None            # in | out (of tolerance) | None: not stated
    found_error: float | None = None    # in the item's own unit (its model's spec)
    found_error_u: float | None = None  # expanded uncertainty of the as-found error
    recorded_utc: str = ""
    recorded_by: str = ""

    def as_found(self) -> str:
        parts = {"in": ["found in tolerance"], "out": ["found OUT of tolerance"]}.get(
            self.found or "", [])
        if self.found_error is not None:
            parts.append(f"as-found error {self.found_error:g}" + (
                "" if self.found_error_u is None else f" +/- {self.found_error_u:g}"))
        return ", ".join(parts) or "as found: not stated"


@dataclass(frozen=True)
class Equipment:
    serial: str
    model: str
    certificate: str | None     # the calibration recorded last (None: identity only)
    issuer: str | None
    due: dt.date | None
    deviations: tuple[Deviation, ...] = ()
    identity_only: bool = False
    calibrations: tuple[Calibration, ...] = ()     # oldest first

    def in_force(self, day: dt.date) -> Calibration | None:
        """The calibration in force on `day`: the latest calibrated on or before it."""
        before = [c for c in self.calibrations
                  if c.calibrated_on is None or c.calibrated_on <= day]
        return before[-1] if before else None

    def deviation_on(self, day: dt.date) -> Deviation | None:
        return next((d for d in self.deviations if d.covers(day)), None)

    def problem_on(self, day: dt.date) -> str | None:
        """Why this item may not be used on `day` (None: it may, or a deviation allows)."""
        if self.identity_only:
            return None
        cal = self.in_force(day)
        if cal is None:
            return (f"{self.model} serial {self.serial}: no calibration recorded on or "
                    f"before {day.isoformat()}")
        if cal.due >= day or self.deviation_on(day) is not None:
            return None
        return (f"{self.model} serial {self.serial}: calibration ({cal.certificate}, "
                f"{cal.issuer}) was due {cal.due.isoformat()}, before {day.isoformat()}")


@dataclass(frozen=True)
class Revision:
    number: str
    revision: int
    issued_utc: str
    signatory: str
    signatory_name: str
    meaning: str
    reason: str | None
    result_sha256: str
    pdf_sha256: str
    dcc_sha256: str
    html_sha256: str
    withdrawn_utc: str | None
    audit_digest: str | None
    withdrawn_reason: str | None = None
    withdrawn_by: str | None = None

    @property
    def status(self) -> str:
        return "withdrawn" if self.withdrawn_utc else "issued"

    @property
    def shown_number(self) -> str:
        """As printed: the number for revision 1, `<number>-R<n>` after it."""
        return self.number if self.revision <= 1 else f"{self.number}-R{self.revision}"

    def digests(self) -> dict[str, str]:
        return {layout.RESULT: self.result_sha256, layout.CERTIFICATE_PDF: self.pdf_sha256,
                layout.CERTIFICATE_DCC: self.dcc_sha256, layout.CERTIFICATE_HTML: self.html_sha256}


@dataclass(frozen=True)
class RunEvent:
    """A session (a resume) or an analysis of a registered run, as the register saw it."""

    utc: str
    kind: str                       # start | resume | session (its result) | analysis
    detail: dict[str, object]


@dataclass(frozen=True)
class RunRecord:
    """A run as the register holds it from its start (issue 54): the issue is made from
    this, and refused when the run's folder no longer matches it (runs.py)."""

    uid: str
    bench: str
    performer: str | None           # the account authenticated at the start (None: none)
    version: str                    # ratebench's version at the start
    simulated: bool
    inputs: dict[str, str]          # procedure.yaml, stand.yaml, lab.yaml: SHA-256 as used
    items: tuple[dict[str, object], ...]    # each stand item's status at the start
    registered_utc: str             # the register's clock
    via: str                        # the bench (and address) that registered it
    result_sha256: str | None = None
    result: str | None = None       # result.json as delivered (UTF-8 text)
    result_utc: str | None = None
    raw: dict[str, str] = field(default_factory=dict)   # raw capture: SHA-256
    events: tuple[RunEvent, ...] = ()

    @property
    def result_bytes(self) -> bytes | None:
        return None if self.result is None else self.result.encode("utf-8")


def _account(r: RowMapping) -> Account:
    return Account(r["name"], r["full_name"], tuple(x for x in r["roles"].split(",") if x),
                   r["function"], bool(r["active"]), bool(r.get("must_change")),
                   r.get("password_changed_utc") or r.get("created_utc"))


def _utc(text: str) -> dt.datetime:
    return dt.datetime.strptime(text[:19], "%Y-%m-%dT%H:%M:%S").replace(tzinfo=dt.UTC)


def _stamp(t: dt.datetime) -> str:
    return t.strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def _revision(r: RowMapping) -> Revision:
    return Revision(*(r[c.name] for c in s.revisions.columns if c.name != "id"))


class Register:
    """One connection pool to one register; `open` migrates it to the newest schema."""

    def __init__(self, url: str, engine: Engine) -> None:
        self.url = url
        self.engine = engine
        self.pg = engine.dialect.name == "postgresql"
        self._pending: dict[tuple[str, str], str] = {}   # begin_issue's times
        #: how messages name this register (the service names itself, not its database)
        self.shown = redact(url)

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

    def close(self) -> None:
        self.engine.dispose()

    def __enter__(self) -> Register:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _migrate(self) -> None:
        upgrade_to_head(self.engine, MIGRATIONS)

    @contextmanager
    def _tx(self) -> Iterator[Connection]:
        try:
            with self.engine.begin() as conn:
                if self.pg:
                    from bench.app.register.pgsql import LOCK_KEY

                    conn.execute(sa.text("SELECT pg_advisory_xact_lock(:k)"), {"k": LOCK_KEY})
                yield conn
        except DBAPIError as e:
            raise RegisterError(_db_message(e)) from e

    # -- the audit trail ------------------------------------------------------------------

    def _append(self, conn: Connection, actor: str, action: str, obj: str,
                detail: Mapping[str, object] | str = "") -> str:
        text = _with_via(detail)
        if self.pg:
            return str(conn.execute(sa.text("SELECT reg_audit_append(:a, :b, :c, :d)"),
                                    {"a": actor, "b": action, "c": obj, "d": text}).scalar())
        head = conn.execute(sa.select(s.audit_head).where(s.audit_head.c.id == 1)).first()
        seq = (head.seq if head else 0) + 1
        prev = head.digest if head else chain.GENESIS
        utc, user = _now_utc(), _os_user()
        digest = chain.entry_digest(prev, seq, utc, actor, action, obj, text, user)
        conn.execute(s.audit.insert().values(seq=seq, utc=utc, actor=actor, action=action,
                                             object=obj, detail=text, db_user=user,
                                             prev_digest=prev, digest=digest))
        if head:
            conn.execute(s.audit_head.update().where(s.audit_head.c.id == 1)
                         .values(seq=seq, digest=digest))
        else:
            conn.execute(s.audit_head.insert().values(id=1, seq=seq, digest=digest))
        return digest

    def append(self, actor: str, action: str, obj: str,
               detail: Mapping[str, object] | str = "") -> str:
        """One audit entry on its own (a run registered, a review, a refused login)."""
        with self._tx() as conn:
            return self._append(conn, actor, action, obj, detail)

    def audit_rows(self) -> list[dict[str, object]]:
        with self.engine.connect() as c:
            return [dict(r._mapping) for r in c.execute(
                sa.select(s.audit).order_by(s.audit.c.seq))]

    def audit_check(self) -> chain.ChainReport:
        with self.engine.connect() as c:
            rows = [dict(r._mapping) for r in c.execute(sa.select(s.audit)
                                                         .order_by(s.audit.c.seq))]
            head = c.execute(sa.select(s.audit_head).where(s.audit_head.c.id == 1)).first()
        return chain.check_chain(rows, None if head is None else dict(head._mapping))

    # -- accounts -------------------------------------------------------------------------

    def accounts(self) -> list[Account]:
        with self.engine.connect() as c:
            return [_account(r._mapping) for r in c.execute(
                sa.select(s.accounts).order_by(s.accounts.c.name))]

    def account(self, name: str) -> Account | None:
        with self.engine.connect() as c:
            r = c.execute(sa.select(s.accounts).where(s.accounts.c.name == name)).first()
        return None if r is None else _account(r._mapping)

    def init(self, admin: str, full_name: str, password: str) -> bool:
        """The first admin account (False: the register has accounts already). The admin
        chooses this password, so it need not be changed at the first login."""
        pw = hash_password(password, admin)
        with self._tx() as conn:
            if conn.execute(sa.select(sa.func.count()).select_from(s.accounts)).scalar():
                return False
            self._insert_account(conn, admin, admin, full_name, ("admin",), None, pw,
                                 must_change=False)
        return True

    def _insert_account(self, conn: Connection, actor: str, name: str, full_name: str,
                        roles: Sequence[str], function: str | None, pw_hash: str,
                        must_change: bool = True) -> None:
        bad = [r for r in roles if r not in ROLES]
        if bad or not roles:
            raise RegisterError(f"roles must be among {', '.join(ROLES)} (got "
                                f"{', '.join(roles) or 'none'})")
        _check_roles(conn, name, full_name, set(roles))
        now = _now_utc()
        try:
            conn.execute(s.accounts.insert().values(
                name=name, full_name=full_name, roles=",".join(sorted(set(roles))),
                function=function, password_hash=pw_hash, active=True,
                created_utc=now, created_by=actor, must_change=must_change,
                password_changed_utc=now))
        except IntegrityError as e:
            raise RegisterError(f"account {name!r} exists") from e
        self._append(conn, actor, "account added", name,
                     {"roles": sorted(set(roles)), "full_name": full_name,
                      "function": function, "password_to_change": must_change})

    def add_account(self, by: Account, name: str, full_name: str, roles: Sequence[str],
                    password: str, function: str | None = None) -> Account:
        """A new account; the admin set its password, so its holder changes it before the
        account signs or runs anything (issue 53)."""
        if not by.has("admin"):
            raise AuthError(f"{by.name} is not an admin: only an admin adds accounts")
        pw = hash_password(password, name)
        with self._tx() as conn:
            self._insert_account(conn, by.name, name, full_name, roles, function, pw)
        acct = self.account(name)
        assert acct is not None
        return acct

    def int_setting(self, key: str) -> int:
        value = self.setting(key)
        try:
            return int(value) if value is not None else SETTING_DEFAULTS[key]
        except ValueError:
            return SETTING_DEFAULTS[key]

    def authenticate(self, name: str, password: str, role: str | None = None,
                     changing_password: bool = False) -> Account:
        """The account, when the password is its own and it holds `role`; else AuthError
        (the same words whether the name or the password was wrong). Every attempt is in
        the audit trail; `lockout_attempts` failures within `lockout_window_s` lock the
        name for `lockout_s`, even against the right password. A password an admin set,
        or one older than `password_max_age_days`, opens only its own change."""
        attempts = self.int_setting("lockout_attempts")
        window_s = self.int_setting("lockout_window_s")
        lock_s = self.int_setting("lockout_s")
        max_age_d = self.int_setting("password_max_age_days")
        try:
            locked = self._lock_state(name)
        except (DBAPIError, RegisterError) as e:
            raise RegisterError(
                f"register {redact(self.url)}: this database role cannot check passwords "
                f"({e}); a lab names its register service in the lab file "
                "(register: https://...), docs/register.md") from e
        if locked is not None:
            self.append(name, "authentication refused", name,
                        {"role": role, "why": f"locked until {locked}"})
            raise AuthError(f"{name!r}: locked after {attempts} failed attempts, until "
                            f"{locked} UTC (register {self.shown})")
        with self.engine.connect() as c:
            r = c.execute(sa.select(s.accounts).where(s.accounts.c.name == name)).first()
        ok = r is not None and bool(r.active) and _verify(r.password_hash, password)
        if not ok:
            until = self._failed(name, role, attempts, window_s, lock_s)
            raise AuthError(f"{name!r}: unknown account, wrong password or account disabled "
                            f"(register {self.shown})"
                            + (f"; now locked until {until} UTC" if until else ""))
        assert r is not None
        acct = _account(r._mapping)
        self._succeeded(name)
        if role is not None and not acct.has(role):
            self.append(name, "authentication refused", name, {"role": role,
                                                                "why": "role not held"})
            raise AuthError(f"{name!r} does not hold the {role} role in register "
                            f"{self.shown} (roles: {', '.join(acct.roles)})")
        if not changing_password:
            stale = ("was set by an admin" if acct.must_change else
                     f"is older than {max_age_d} days" if acct.password_changed_utc and
                     _utc(acct.password_changed_utc) + dt.timedelta(days=max_age_d)
                     < dt.datetime.now(dt.UTC) else None)
            if stale:
                self.append(name, "authentication refused", name,
                            {"role": role, "why": f"password {stale}"})
                raise AuthError(f"{name!r}: the password {stale}; change it first: bench "
                                f"register user passwd '{name}' --as '{name}'")
        self.append(name, "authenticated", name, {"role": role})
        return acct

    def _lock_state(self, name: str) -> str | None:
        """The time the name's lock ends, while it is locked; an ended lock is lifted
        (and audited) here."""
        with self.engine.connect() as c:
            r = c.execute(sa.select(s.logins).where(s.logins.c.name == name)).first()
        if r is None or not r.locked_until_utc:
            return None
        if _utc(r.locked_until_utc) > dt.datetime.now(dt.UTC):
            return str(r.locked_until_utc)[:19]
        with self._tx() as conn:
            done = conn.execute(s.logins.update().where(s.logins.c.name == name)
                                .where(s.logins.c.locked_until_utc == r.locked_until_utc)
                                .values(failures=0, first_failure_utc=None,
                                        locked_until_utc=None)).rowcount
            if done:
                self._append(conn, name, "account unlocked", name,
                             {"lock_ended_utc": r.locked_until_utc})
        return None

    def _failed(self, name: str, role: str | None, attempts: int, window_s: int,
                lock_s: int) -> str | None:
        """Count a failed attempt under the register's lock; the lock's end when this one
        locks the name."""
        now = dt.datetime.now(dt.UTC)
        with self._tx() as conn:
            r = conn.execute(sa.select(s.logins).where(s.logins.c.name == name)).first()
            fresh = (r is None or not r.first_failure_utc
                     or _utc(r.first_failure_utc) + dt.timedelta(seconds=window_s) < now)
            failures = 1 if fresh or r is None else int(r.failures) + 1
            first = _stamp(now) if fresh or r is None else r.first_failure_utc
            until = _stamp(now + dt.timedelta(seconds=lock_s)) if failures >= attempts \
                else None
            values = {"failures": failures, "first_failure_utc": first,
                      "locked_until_utc": until}
            if r is None:
                conn.execute(s.logins.insert().values(name=name, **values))
            else:
                conn.execute(s.logins.update().where(s.logins.c.name == name).values(**values))
            self._append(conn, name, "authentication refused", name,
                         {"role": role, "failures_in_window": failures})
            if until:
                self._append(conn, name, "account locked", name,
                             {"failures": failures, "window_s": window_s,
                              "locked_until_utc": until})
        return until[:19] if until else None

    def _succeeded(self, name: str) -> None:
        with self._tx() as conn:
            conn.execute(s.logins.delete().where(s.logins.c.name == name))

    # -- account lifecycle (issue 53): each change an audit entry naming old and new ------

    def change_password(self, name: str, old: str, new: str) -> None:
        """The holder changes their own password (an admin-set or expired one included)."""
        acct = self.authenticate(name, old, changing_password=True)
        if new == old:
            raise RegisterError("the new password is the old one")
        pw = hash_password(new, acct.name)
        with self._tx() as conn:
            conn.execute(s.accounts.update().where(s.accounts.c.name == name).values(
                password_hash=pw, must_change=False, password_changed_utc=_now_utc()))
            self._append(conn, name, "password changed", name,
                         {"old": "password set by an admin" if acct.must_change
                          else "own password", "new": "own password"})

    def reset_password(self, by: Account, name: str, new: str) -> None:
        """An admin sets another account's password; its holder must change it."""
        if not by.has("admin"):
            raise AuthError(f"{by.name} is not an admin: only an admin resets a password")
        target = self._existing(name)
        pw = hash_password(new, target.name)
        with self._tx() as conn:
            conn.execute(s.accounts.update().where(s.accounts.c.name == name).values(
                password_hash=pw, must_change=True, password_changed_utc=_now_utc()))
            conn.execute(s.logins.delete().where(s.logins.c.name == name))
            self._append(conn, by.name, "password reset", name,
                         {"old": "own password", "new": "password set by an admin, to be "
                          "changed at the next login"})

    def set_active(self, by: Account, name: str, active: bool) -> Account:
        if not by.has("admin"):
            raise AuthError(f"{by.name} is not an admin: only an admin disables or enables")
        target = self._existing(name)
        if by.name == name and not active:
            raise RegisterError("an admin does not disable their own account")
        with self._tx() as conn:
            if active:
                _check_roles(conn, name, target.full_name, set(target.roles))
            conn.execute(s.accounts.update().where(s.accounts.c.name == name)
                         .values(active=active))
            self._append(conn, by.name, "account enabled" if active else "account disabled",
                         name, {"old": "active" if target.active else "disabled",
                                "new": "active" if active else "disabled"})
        return self._existing(name)

    def set_role(self, by: Account, name: str, role: str, grant: bool) -> Account:
        if not by.has("admin"):
            raise AuthError(f"{by.name} is not an admin: only an admin changes roles")
        if role not in ROLES:
            raise RegisterError(f"role {role!r}: one of {', '.join(ROLES)}")
        target = self._existing(name)
        roles = set(target.roles) | {role} if grant else set(target.roles) - {role}
        if not roles:
            raise RegisterError(f"{name} would hold no role: disable the account instead")
        with self._tx() as conn:
            if target.active:
                _check_roles(conn, name, target.full_name, roles)
            conn.execute(s.accounts.update().where(s.accounts.c.name == name)
                         .values(roles=",".join(sorted(roles))))
            self._append(conn, by.name, "role granted" if grant else "role revoked", name,
                         {"role": role, "old": sorted(target.roles), "new": sorted(roles)})
        return self._existing(name)

    def _existing(self, name: str) -> Account:
        acct = self.account(name)
        if acct is None:
            raise RegisterError(f"no account {name!r}")
        return acct

    # -- equipment ------------------------------------------------------------------------

    def add_equipment(self, by: Account, serial: str, model: str, certificate: str | None,
                      issuer: str | None, due: dt.date | None, identity_only: bool = False,
                      calibrated_on: dt.date | None = None) -> None:
        """An item with its calibration, or (identity_only) one without any: a drive or a
        fixture, looked up by serial and model, never overdue."""
        if not (by.has("quality") or by.has("admin")):
            raise AuthError(f"{by.name} holds neither the quality nor the admin role")
        if identity_only and (certificate or issuer or due):
            raise RegisterError("an identity-only item has no certificate, issuer or due date")
        if not identity_only and not (certificate and issuer and due):
            raise RegisterError("an item with a calibration states --certificate, --issuer "
                                "and --due (or is --identity-only)")
        now = _now_utc()
        with self._tx() as conn:
            try:
                conn.execute(s.equipment.insert().values(
                    serial=serial, model=model, certificate=certificate or _NONE(conn),
                    issuer=issuer or _NONE(conn),
                    due_date=due.isoformat() if due else _NONE(conn), added_utc=now,
                    added_by=by.name, identity_only=identity_only))
            except IntegrityError as e:
                raise RegisterError(f"equipment {serial!r} is in the inventory") from e
            if not identity_only:
                assert certificate and issuer and due
                self._insert_calibration(conn, by, serial, Calibration(
                    certificate, issuer, calibrated_on, due))
            self._append(conn, by.name, "equipment added", serial,
                         {"model": model, "certificate": certificate, "issuer": issuer,
                          "due": due.isoformat() if due else None,
                          "identity_only": identity_only})

    def _insert_calibration(self, conn: Connection, by: Account, serial: str,
                            c: Calibration) -> None:
        conn.execute(s.calibrations.insert().values(
            serial=serial, certificate=c.certificate, issuer=c.issuer,
            calibrated_on=c.calibrated_on.isoformat() if c.calibrated_on else None,
            due_date=c.due.isoformat(),
            found=c.found, found_error=c.found_error, found_error_u=c.found_error_u,
            recorded_utc=_now_utc(), recorded_by=by.name))
        conn.execute(s.equipment.update().where(s.equipment.c.serial == serial).values(
            certificate=c.certificate, issuer=c.issuer, due_date=c.due.isoformat()))

    def update_equipment(self, by: Account, serial: str, certificate: str, issuer: str,
                         due: dt.date, calibrated_on: dt.date | None = None,
                         found: str | None = None, found_error: float | None = None,
                         found_error_u: float | None = None) -> Calibration:
        """A new calibration of an item: recorded beside the earlier ones, with how the
        item was found (in or out of tolerance, and by how much)."""
        if not (by.has("quality") or by.has("admin")):
            raise AuthError(f"{by.name} holds neither the quality nor the admin role")
        if found not in (None, "in", "out"):
            raise RegisterError(f"--found {found}: in or out (of tolerance)")
        if found_error_u is not None and (found_error is None or found_error_u < 0):
            raise RegisterError("an as-found uncertainty goes with an as-found error, >= 0")
        item = next(iter(self.equipment(serial)), None)
        if item is None:
            raise RegisterError(f"equipment {serial!r} is not in the inventory")
        if item.identity_only:
            raise RegisterError(f"equipment {serial!r} is identity-only: it has no "
                                "calibration to update")
        on = calibrated_on or dt.datetime.now(dt.UTC).date()
        if due <= on:
            raise RegisterError(f"--due {due.isoformat()} is not after the calibration "
                                f"({on.isoformat()})")
        cal = Calibration(certificate, issuer, on, due, found, found_error, found_error_u)
        with self._tx() as conn:
            self._insert_calibration(conn, by, serial, cal)
            self._append(conn, by.name, "equipment recalibrated", serial, {
                "old": {"certificate": item.certificate, "issuer": item.issuer,
                        "due": item.due.isoformat() if item.due else None},
                "new": {"certificate": certificate, "issuer": issuer, "due": due.isoformat(),
                        "calibrated_on": on.isoformat()},
                "as_found": {"found": found, "error": found_error, "error_U": found_error_u}})
        return cal

    def add_deviation(self, by: Account, serial: str, reason: str, expires: dt.date) -> None:
        """A quality account's recorded decision to use an overdue item until `expires`:
        only for an item that is overdue today, expiring in the future and at most
        `deviation_max_days` ahead, with its reason in a sentence (ISO/IEC 17025 7.10)."""
        if not by.has("quality"):
            raise AuthError(f"{by.name} does not hold the quality role: only quality "
                            "records a deviation")
        why = reason.strip()
        if len(why) < 20 or len(why.split()) < 4:
            raise RegisterError("a deviation states its reason in a sentence (at least four "
                                "words)")
        today = dt.datetime.now(dt.UTC).date()
        most = self.int_setting("deviation_max_days")
        if expires <= today:
            raise RegisterError(f"--expires {expires.isoformat()} is not in the future")
        if (expires - today).days > most:
            raise RegisterError(f"--expires {expires.isoformat()} is more than {most} days "
                                "ahead (the register's deviation_max_days)")
        item = next(iter(self.equipment(serial)), None)
        if item is None:
            raise RegisterError(f"equipment {serial!r} is not in the inventory")
        if item.identity_only:
            raise RegisterError(f"equipment {serial!r} is identity-only: never overdue")
        cal = item.in_force(today)
        if cal is not None and cal.due >= today:
            raise RegisterError(f"equipment {serial!r} is in date (calibration "
                                f"{cal.certificate} due {cal.due.isoformat()}): a deviation "
                                "is for an overdue item")
        with self._tx() as conn:
            conn.execute(s.deviations.insert().values(
                serial=serial, reason=why, expires=expires.isoformat(),
                recorded_by=by.name, recorded_utc=_now_utc()))
            self._append(conn, by.name, "deviation recorded", serial,
                         {"reason": why, "expires": expires.isoformat()})

    def revoke_deviation(self, by: Account, serial: str) -> int:
        """End the deviations in force for an item (quality); returns how many."""
        if not by.has("quality"):
            raise AuthError(f"{by.name} does not hold the quality role")
        today = dt.datetime.now(dt.UTC).date().isoformat()
        d = s.deviations.c
        with self._tx() as conn:
            n = conn.execute(s.deviations.update().where(d.serial == serial)
                             .where(d.revoked_utc.is_(None)).where(d.expires >= today)
                             .values(revoked_utc=_now_utc(), revoked_by=by.name)).rowcount
            if not n:
                raise RegisterError(f"equipment {serial!r} has no deviation in force")
            self._append(conn, by.name, "deviation revoked", serial, {"revoked": n})
        return int(n)

    def equipment(self, serial: str | None = None) -> list[Equipment]:
        q = sa.select(s.equipment).order_by(s.equipment.c.serial)
        if serial is not None:
            q = q.where(s.equipment.c.serial == serial)
        with self.engine.connect() as c:
            rows = [r._mapping for r in c.execute(q)]
            devs: dict[str, list[Deviation]] = {}
            for d in c.execute(sa.select(s.deviations).order_by(s.deviations.c.id)):
                devs.setdefault(d.serial, []).append(Deviation(
                    d.reason, dt.date.fromisoformat(d.expires), d.recorded_by,
                    d.recorded_utc, d.revoked_utc, d.revoked_by))
            cals: dict[str, list[Calibration]] = {}
            for k in c.execute(sa.select(s.calibrations).order_by(
                    s.calibrations.c.calibrated_on.is_not(None), s.calibrations.c.calibrated_on,
                    s.calibrations.c.id)):
                cals.setdefault(k.serial, []).append(Calibration(  # unstated dates first
                    k.certificate, k.issuer,
                    dt.date.fromisoformat(k.calibrated_on) if k.calibrated_on else None,
                    dt.date.fromisoformat(k.due_date), k.found, k.found_error,
                    k.found_error_u, k.recorded_utc, k.recorded_by))
        return [Equipment(r["serial"], r["model"], r["certificate"] or None,
                          r["issuer"] or None,
                          dt.date.fromisoformat(r["due_date"]) if r["due_date"] else None,
                          tuple(devs.get(r["serial"], ())), bool(r["identity_only"]),
                          tuple(cals.get(r["serial"], ()))) for r in rows]

    # -- settings -------------------------------------------------------------------------

    def setting(self, key: str) -> str | None:
        with self.engine.connect() as c:
            return c.execute(sa.select(s.settings.c.value)
                             .where(s.settings.c.key == key)).scalar()

    def issuer(self) -> dict[str, str]:
        """The issuer's identity the register holds (the keys of ISSUER_KEYS it has)."""
        held = {k: self.setting(k) for k in ISSUER_KEYS}
        return {k: v for k, v in held.items() if v}

    def set_setting(self, by: Account, key: str, value: str) -> None:
        if not by.has("admin"):
            raise AuthError(f"{by.name} is not an admin")
        if key in SETTING_DEFAULTS and not (value.isdigit() and int(value) > 0):
            raise RegisterError(f"setting {key}: a whole number above 0 (got {value!r})")
        if key == "issuer.prefix" and not re.fullmatch(r"[A-Z][A-Z0-9]{0,11}", value):
            raise RegisterError(f"setting issuer.prefix: 1 to 12 capital letters and digits "
                                f"(got {value!r})")
        if key.startswith("issuer.") and (key not in ISSUER_KEYS or not value.strip()):
            raise RegisterError(f"setting {key}: one of {', '.join(ISSUER_KEYS)}, not empty")
        old = self.setting(key)
        with self._tx() as conn:
            conn.execute(s.settings.delete().where(s.settings.c.key == key))
            conn.execute(s.settings.insert().values(key=key, value=value))
            self._append(conn, by.name, "setting changed", key,
                         {"old": old if old is not None else
                          (f"{SETTING_DEFAULTS[key]} (default)" if key in SETTING_DEFAULTS
                           else None), "new": value})

    # -- certificate numbers and revisions ------------------------------------------------

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

    # -- runs, from their start (issue 54) -------------------------------------------------

    def register_run(self, uid: str, bench: str, performer: str | None, version: str,
                     simulated: bool, inputs: Mapping[str, str],
                     items: Sequence[Mapping[str, object]]) -> RunRecord:
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
                simulated=simulated, inputs=json.dumps(dict(inputs), sort_keys=True),
                items=json.dumps([dict(i) for i in items], sort_keys=True),
                registered_utc=utc, via=via, raw="{}"))
            conn.execute(s.run_events.insert().values(uid=uid, utc=utc, kind="start",
                                                      detail=json.dumps({"via": via})))
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
                                                      detail=json.dumps(detail)))
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
            row = self._known_run(conn, uid)
            seen: dict[str, str] = json.loads(row.raw)
            changed = sorted(k for k, v in raw.items() if k in seen and seen[k] != v)
            gone = sorted(k for k in seen if k not in raw)
            if changed or gone:
                raise RegisterError(f"run {uid}: " + "; ".join(
                    [f"raw capture {k} changed since the register saw it" for k in changed]
                    + [f"raw capture {k} is missing (the register saw it)" for k in gone]))
            conn.execute(s.runs.update().where(s.runs.c.uid == uid).values(
                result_sha256=digest, result=text, result_utc=utc,
                raw=json.dumps({**seen, **raw}, sort_keys=True)))
            detail = {"result_sha256": digest, "raw_captures": len(raw),
                      "reason": reason, "via": ACTING_VIA.get() or "this bench"}
            conn.execute(s.run_events.insert().values(uid=uid, utc=utc, kind=kind,
                                                      detail=json.dumps(detail)))
            self._append(conn, f"bench {row.bench}", f"run {kind} result", uid, detail)
        return self._run_record(uid)

    def run_record(self, uid: str) -> RunRecord | None:
        with self.engine.connect() as c:
            r = c.execute(sa.select(s.runs).where(s.runs.c.uid == uid)).first()
            if r is None:
                return None
            events = tuple(RunEvent(e.utc, e.kind, json.loads(e.detail)) for e in c.execute(
                sa.select(s.run_events).where(s.run_events.c.uid == uid)
                .order_by(s.run_events.c.id)))
        return RunRecord(r.uid, r.bench, r.performer, r.version, bool(r.simulated),
                         json.loads(r.inputs), tuple(json.loads(r.items)), r.registered_utc,
                         r.via, r.result_sha256, r.result, r.result_utc, json.loads(r.raw),
                         events)

    def runs_using(self, serial: str) -> list[RunRecord]:
        """Every run whose record of its start names the item `serial` among the stand's
        items (issue 58: what a finding on the item touches), oldest first."""
        with self.engine.connect() as c:
            rows = c.execute(sa.select(s.runs).order_by(s.runs.c.registered_utc,
                                                        s.runs.c.uid)).all()
        uids = [r.uid for r in rows
                if any(isinstance(i, dict) and i.get("serial") == serial
                       for i in json.loads(r.items))]
        return [self._run_record(u) for u in uids]

    def impact_assessed(self, by: Account, serial: str,
                        detail: Mapping[str, object]) -> str:
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

    def _known_run(self, conn: Connection, uid: str) -> sa.Row[tuple[object, ...]]:
        row = conn.execute(sa.select(s.runs).where(s.runs.c.uid == uid)).first()
        if row is None:
            raise RegisterError(f"run {uid} was not registered at its start")
        return row

    #: a register reached over the network (client.ServiceRegister), not a database here
    remote = False

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
              detail: Mapping[str, object]) -> Revision:
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
        d = self._append(conn, a["s"], "issue" if not last else "re-issue",
                         f"{a['n']} revision {a['r']}", json.loads(a["d"]))
        conn.execute(s.revisions.insert().values(
            number=a["n"], revision=a["r"], issued_utc=a["t"], signatory=a["s"],
            signatory_name=r.full_name, meaning=a["m"], reason=a["why"].strip() or None,
            result_sha256=a["res"], pdf_sha256=a["pdf"], dcc_sha256=a["dcc"],
            html_sha256=a["html"], audit_digest=d))


def _NONE(conn: Connection) -> str | None:  # noqa: N802 - reads as the value it stands for
    """No value: NULL, or '' in an SQLite register made before g0003 (its columns stay NOT
    NULL); read back as None either way."""
    if conn.dialect.name != "sqlite":
        return None
    cols = conn.exec_driver_sql("PRAGMA table_info(reg_equipment)").all()
    return "" if any(c[1] == "certificate" and c[3] for c in cols) else None


def _with_via(detail: Mapping[str, object] | str) -> str:
    """An audit entry's detail as stored, naming the bench or station the person acted
    through when the register service serves the request."""
    via = ACTING_VIA.get()
    if via:
        base: dict[str, object] = ({"detail": detail} if isinstance(detail, str) and detail
                                   else {} if isinstance(detail, str) else dict(detail))
        detail = {**base, "via": via}
    return detail if isinstance(detail, str) else json.dumps(detail, sort_keys=True)


def _check_roles(conn: Connection, name: str, full_name: str, roles: set[str]) -> None:
    """ISO/IEC 17025 6.2.5: who administers accounts does not sign, and a printed name
    under a signature identifies one active signatory."""
    if {"admin", "signatory"} <= roles:
        raise RegisterError("the admin and signatory roles are never held by one account "
                            "(the person who sets passwords does not also sign)")
    if "signatory" not in roles:
        return
    for r in conn.execute(sa.select(s.accounts.c.name, s.accounts.c.roles)
                          .where(s.accounts.c.full_name == full_name)
                          .where(s.accounts.c.active.is_(True))
                          .where(s.accounts.c.name != name)):
        if "signatory" in r.roles.split(","):
            raise RegisterError(f"the full name {full_name!r} is already printed under "
                                f"signatures of the active signatory {r.name!r}")


def _sqlite_file(url: str, create: bool) -> None:
    """A register file is readable by its owner alone (mode 0600: the password hashes are
    in it); a missing one is an error unless the command creates registers."""
    try:
        u = sa.engine.make_url(url)
    except sa.exc.ArgumentError as e:
        raise RegisterError(f"register {url!r}: not a database URL ({e})") from None
    if u.get_backend_name() != "sqlite" or not u.database or u.database == ":memory:":
        return
    path = Path(u.database)
    if not path.exists():
        if not create:
            raise RegisterError(f"register {url}: no such file (bench register init "
                                "creates a register; nothing was created)")
        path.parent.mkdir(parents=True, exist_ok=True)
        os.close(os.open(path, os.O_CREAT | os.O_WRONLY, 0o600))
    elif create and path.stat().st_mode & 0o077 and path.stat().st_uid == os.geteuid():
        path.chmod(0o600)


def _db_message(e: DBAPIError) -> str:
    text = str(e.orig).strip().splitlines()[0] if e.orig is not None else str(e)
    return text if text.startswith("register:") else f"register: {text}"


def redact(url: str) -> str:
    """The URL without its password, for messages."""
    try:
        return sa.engine.make_url(url).render_as_string(hide_password=True)
    except Exception:  # noqa: BLE001 - a message must not fail on a malformed URL
        return url
