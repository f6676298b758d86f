"""The register's database and its audit trail: the connection, the one transaction a
change is (with its audit entry), the hash-chained trail, and the register's settings.

The lowest class of the register's chain (store.py `Register`).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager

import sqlalchemy as sa
from sqlalchemy.engine import Connection, Engine
from sqlalchemy.exc import DBAPIError

from bench.app.db import upgrade_to_head
from bench.app.register import chain
from bench.app.register import schema as s
from bench.app.register.model import (
    ISSUER_KEYS,
    MIGRATIONS,
    SETTING_DEFAULTS,
    Account,
    AuditDetail,
    AuditEntry,
    AuthError,
    RegisterError,
    _db_message,
    _now_utc,
    _os_user,
    _with_via,
    redact,
)


def _entries(c: Connection) -> list[AuditEntry]:
    """The audit trail's entries as stored, in their order."""
    a = s.audit.c
    return [AuditEntry(r.seq, r.utc, r.actor, r.action, r.object, r.detail, r.db_user,
                       r.prev_digest, r.digest)
            for r in c.execute(sa.select(s.audit).order_by(a.seq))]


class RegisterTrail:
    """One connection pool to one register, and the audit trail every change appends to."""

    def __init__(self, url: str, engine: Engine) -> None:
        self.url = url
        self.engine = engine
        self.pg = engine.dialect.name == "postgresql"
        self._pending: dict[tuple[str, str], str] = {}   # begin_issue's times
        #: how messages name this register (the service names itself, not its database)
        self.shown = redact(url)

    def close(self) -> None:
        self.engine.dispose()

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

    def _append(self, conn: Connection, actor: str, action: str, obj: str,
                detail: AuditDetail | str = "") -> str:
        return self._append_text(conn, actor, action, obj, _with_via(detail))

    def _append_text(self, conn: Connection, actor: str, action: str, obj: str,
                     text: str) -> str:
        """The entry with its detail as stored (and hashed): `_with_via`'s text."""
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
               detail: AuditDetail | str = "") -> str:
        """One audit entry on its own (a run registered, a review, a refused login)."""
        with self._tx() as conn:
            return self._append(conn, actor, action, obj, detail)

    def audit_rows(self) -> list[AuditEntry]:
        with self.engine.connect() as c:
            return _entries(c)

    def audit_check(self) -> chain.ChainReport:
        with self.engine.connect() as c:
            rows = _entries(c)
            head = c.execute(sa.select(s.audit_head).where(s.audit_head.c.id == 1)).first()
        return chain.check_chain(rows, None if head is None else (head.seq, head.digest))

    def setting(self, key: str) -> str | None:
        with self.engine.connect() as c:
            return c.execute(sa.select(s.settings.c.value)
                             .where(s.settings.c.key == key)).scalar()

    def int_setting(self, key: str) -> int:
        value = self.setting(key)
        try:
            return int(value) if value is not None else SETTING_DEFAULTS[key]
        except ValueError:
            return SETTING_DEFAULTS[key]

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
