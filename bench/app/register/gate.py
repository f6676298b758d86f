"""Before anything moves (ISO/IEC 17025 6.4.13, 6.2.5): who performs the run, and whether
every item of the stand is in the lab's inventory and within its calibration, as the lab
register says (docs/register.md).

A real stand whose item is overdue, or not in the inventory, is not started unless a
quality account recorded a deviation; on twins the same facts are findings the certificate
states. The performer is the account that authenticated (`bench run --operator NAME`);
without one, nobody is named: the certificate says "not recorded" and gives the OS user.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TypedDict

from bench.app.register.store import (
    Calibration,
    Equipment,
    Register,
    RegisterError,
    redact,
)
from bench.core.config import Traced


@dataclass(frozen=True)
class ItemStatus:
    """One stand item against the inventory: `problem` is why it may not be used."""

    where: str
    item: str
    serial: str | None
    problem: str | None
    deviation: str | None = None       # a recorded deviation that allows its use
    #: the inventory's calibration in force on the run's date (issue 55): what the
    #: certificate's traceability table prints, not the stand file's statement
    in_force: Calibration | None = None
    identity_only: bool = False

    def to_dict(self) -> dict[str, str | None]:
        out = {"where": self.where, "item": self.item, "serial": self.serial,
               "problem": self.problem, "deviation": self.deviation}
        c = self.in_force
        if c is not None:
            out |= {"certificate": c.certificate, "issuer": c.issuer,
                    "calibrated_on": c.calibrated_on.isoformat() if c.calibrated_on else None,
                    "due": c.due.isoformat()}
        if self.identity_only:
            out["identity_only"] = "yes"
        return out


def item_status(t: Traced, found: dict[str, Equipment], on: dt.date) -> ItemStatus:
    """Only items with a stated calibration or a serial are inventory items: a drive with
    neither is driven, not a measuring standard."""
    if t.serial is None:
        if not t.stated:
            return ItemStatus(t.where, t.item, None, None)
        return ItemStatus(t.where, t.item, None, f"{t.item} ({t.where}): the stand file "
                          "states no serial, so the inventory cannot identify it")
    e = found.get(t.serial)
    if e is None:
        return ItemStatus(t.where, t.item, t.serial,
                          f"{t.item} ({t.where}) serial {t.serial}: not in the lab's "
                          "equipment inventory (bench register equipment add)")
    if e.identity_only:
        return ItemStatus(t.where, t.item, t.serial, None, identity_only=True)
    cal = e.in_force(on)
    dev = e.deviation_on(on)
    if cal is not None and cal.due < on and dev is not None:
        return ItemStatus(t.where, t.item, t.serial, None,
                          f"{t.item} serial {t.serial}: calibration due "
                          f"{cal.due.isoformat()}, used under a deviation recorded by "
                          f"{dev.recorded_by} until {dev.expires.isoformat()}: "
                          f"{dev.reason}", cal)
    problem = e.problem_on(on)
    if problem is None and t.stated and cal is not None \
            and (t.certificate, t.due) != (cal.certificate, cal.due):
        # issue 54: the calibration printed is the inventory's; a stand file that says
        # otherwise is a finding on twins and a refusal on a real stand
        problem = (f"{t.item} serial {t.serial}: the stand file states calibration "
                   f"{t.certificate} due {t.due}, the inventory's record in force is "
                   f"{cal.certificate} due {cal.due.isoformat()}")
    return ItemStatus(t.where, t.item, t.serial, problem, in_force=cal)


def equipment_statuses(reg: Register, items: Sequence[Traced], on: dt.date
                       ) -> list[ItemStatus]:
    found = {e.serial: e for e in reg.equipment()}
    return [item_status(t, found, on) for t in items]


def authenticate_performer(reg: Register, name: str, password: Callable[[str], str],
                           run_uid: str | None = None, bench: str | None = None
                           ) -> dict[str, str | None]:
    """The performer as meta.json keeps it: account, full name, register, time; the audit
    entry names the run (its uid) and the bench (issue 57)."""
    acct = reg.authenticate(name, password(f"password of {name} (performer, register "
                                           f"{redact(reg.url)}): "), "operator")
    utc = dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    reg.append(acct.name, "run started by", name,
               {"full_name": acct.full_name, "run_uid": run_uid, "bench": bench})
    return {"account": acct.name, "full_name": acct.full_name, "function": acct.function,
            "register": redact(reg.url), "authenticated_utc": utc}


def open_register(url: str) -> Register:
    try:
        return Register.open(url, migrate=False)
    except RegisterError as e:
        raise RegisterError(f"the lab register cannot be reached: {e}") from None


class StartFacts(TypedDict):
    """What meta.json keeps of the register's word at the run's start, in this key order
    (bench/core/journal_codec.py's `StartMeta` reads it back for the certificate)."""

    performer: dict[str, str | None] | None
    equipment_register: str | None
    equipment_status: list[dict[str, str | None]]


@dataclass(frozen=True)
class StartGate:
    """What the register says before a run starts: `refusal` (not started) or the facts
    meta.json keeps for the certificate."""

    refusal: list[str]
    performer: dict[str, str | None] | None
    equipment: list[dict[str, str | None]]
    register: str | None

    def meta(self) -> StartFacts:
        return {"performer": self.performer, "equipment_register": self.register,
                "equipment_status": self.equipment}


def start_gate(register_url: str | None, items: Sequence[Traced], simulated: bool,
               operator: str | None, password: Callable[[str], str],
               on: dt.date | None = None, run_uid: str | None = None,
               bench: str | None = None, inputs: Mapping[str, str] | None = None,
               session: int | None = None) -> StartGate:
    """Authenticate the performer and check the stand's items, before anything moves;
    then the register records the run's start (`inputs`: the files' digests), or with
    `session` a resume of a run it holds (issue 54)."""
    if register_url is None:
        refusal = ([f"--operator {operator}: the lab file names no register to "
                    "authenticate the performer with (register: URL); without --operator "
                    "the certificate says the performer was not recorded"]
                   if operator else [])
        if not simulated:   # issue 54: no register, no issue; a real stand runs for one
            refusal.append("a real stand runs only under the lab's register (register: URL "
                           "in the lab file, --lab FILE): a run the register did not see "
                           "start can never be issued (docs/register.md)")
        return StartGate(refusal, None, [], None)
    on = on or dt.datetime.now(dt.UTC).date()
    try:
        with open_register(register_url) as reg:
            performer = (authenticate_performer(reg, operator, password, run_uid, bench)
                         if operator else None)
            statuses = equipment_statuses(reg, items, on)
            problems = [s.problem for s in statuses if s.problem]
            refusal = [*problems, "(ISO/IEC 17025 6.4.13: add the item to the inventory, or "
                       "a quality account records a deviation for an overdue one: bench "
                       "register equipment deviation SERIAL --reason TEXT --expires "
                       "YYYY-MM-DD)"] if problems and not simulated else []
            found = [s.to_dict() for s in statuses]
            if not refusal and run_uid is not None:
                _record_start(reg, run_uid, bench or "unnamed bench", performer, simulated,
                              inputs, found, session)
    except RegisterError as e:
        return StartGate([str(e)], None, [], redact(register_url))
    return StartGate(refusal, performer, found, redact(register_url))


def _record_start(reg: Register, uid: str, bench: str,
                  performer: Mapping[str, str | None] | None, simulated: bool,
                  inputs: Mapping[str, str] | None, found: list[dict[str, str | None]],
                  session: int | None) -> None:
    """The register's record of the run from its start: a new run (its inputs' digests),
    or a resume's session of a run it holds (a run it never saw start stays unheld)."""
    from bench.app.register.runs import register_start

    if session is None:
        register_start(reg, uid, bench, performer, simulated, inputs or {}, found)
    elif reg.run_record(uid) is not None:
        account = performer.get("account") if performer else None
        reg.run_session(uid, session, str(account) if account else None)
