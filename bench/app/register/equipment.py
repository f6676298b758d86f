"""The register's equipment inventory: each standard's calibrations (with as-found
errors) and the deviations that allow an overdue item for a while.
"""

from __future__ import annotations

import datetime as dt

import sqlalchemy as sa
from sqlalchemy.engine import Connection
from sqlalchemy.exc import IntegrityError

from bench.app.register import schema as s
from bench.app.register.accounts import RegisterAccounts
from bench.app.register.model import (
    _NONE,
    Account,
    AuthError,
    Calibration,
    Deviation,
    Equipment,
    RegisterError,
    _now_utc,
)


class RegisterEquipment(RegisterAccounts):
    """The equipment inventory, changed by the accounts allowed to."""

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
