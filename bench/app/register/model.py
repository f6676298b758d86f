"""What the lab register holds, as values (accounts, equipment, revisions, runs), its
errors, and what every part of it shares: the password rules, the times as stored, the
acting client (ACTING_VIA), the database's messages. The register itself is the chain of
classes in trail.py, accounts.py, equipment.py and store.py.
"""

from __future__ import annotations

import contextvars
import datetime as dt
import getpass
import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, TypeAlias, TypedDict

import sqlalchemy as sa
from sqlalchemy.engine import Connection, RowMapping
from sqlalchemy.exc import DBAPIError

from bench.app.register import schema as s
from bench.core import rundir_layout as layout
from drivers.json_types import JsonLike

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


#: an audit entry's detail as the caller states it: free-form JSON by design (the trail
#: stores it as text, keys sorted, and hashes that text: chain.py)
AuditDetail: TypeAlias = Mapping[str, JsonLike]
#: one stand item's status at a run's start (gate.ItemStatus.to_dict), as the register keeps it
ItemRow: TypeAlias = Mapping[str, str | None]


@dataclass(frozen=True)
class AuditEntry:
    """One entry of the audit trail as stored (chain.py recomputes its digest)."""

    seq: int
    utc: str
    actor: str
    action: str
    object: str
    detail: str                     # JSON text, as hashed
    db_user: str
    prev_digest: str
    digest: str


@dataclass(frozen=True)
class EventDetail:
    """What the register noted of a run's session or analysis (store.py writes it)."""

    via: str | None = None
    session: int | None = None      # a resume's session number
    performer: str | None = None
    result_sha256: str | None = None
    raw_captures: int | None = None
    reason: str | None = None       # an analysis's reason


@dataclass(frozen=True)
class RunEvent:
    """A session (a resume) or an analysis of a registered run, as the register saw it."""

    utc: str
    kind: str                       # start | resume | session (its result) | analysis
    detail: EventDetail


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
    items: tuple[dict[str, str | None], ...]    # each stand item's status at the start
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


def _NONE(conn: Connection) -> str | None:  # noqa: N802 - reads as the value it stands for
    """No value: NULL, or '' in an SQLite register made before g0003 (its columns stay NOT
    NULL); read back as None either way."""
    if conn.dialect.name != "sqlite":
        return None
    cols = conn.exec_driver_sql("PRAGMA table_info(reg_equipment)").all()
    return "" if any(c[1] == "certificate" and c[3] for c in cols) else None


def _with_via(detail: AuditDetail | str) -> str:
    """An audit entry's detail as stored, naming the bench or station the person acted
    through when the register service serves the request."""
    via = ACTING_VIA.get()
    if via:
        base: dict[str, JsonLike] = ({"detail": detail} if isinstance(detail, str) and detail
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
