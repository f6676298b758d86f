"""The register's accounts: who may sign, run, review or administer, their passwords
(argon2id, checked here where the lockout applies) and their roles.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence

import sqlalchemy as sa
from sqlalchemy.engine import Connection
from sqlalchemy.exc import DBAPIError, IntegrityError

from bench.app.names import ROLES
from bench.app.register import schema as s
from bench.app.register.model import (
    Account,
    AuthError,
    RegisterError,
    _account,
    _check_roles,
    _now_utc,
    _stamp,
    _utc,
    _verify,
    hash_password,
    redact,
)
from bench.app.register.trail import RegisterTrail


class RegisterAccounts(RegisterTrail):
    """The accounts, their authentication and the lockout against guessing."""

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
