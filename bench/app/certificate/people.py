"""The people and the equipment status behind a certificate, stated once for the PDF and
the DCC (issue 42): the performer is the account the lab register authenticated at the
run's start, never a name from a file; the signatory is the account it authenticated at
issue, with the signature's meaning; the equipment is as the register's inventory stood
when the run started."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from bench.report.certificate.parts import NOT_RECORDED

PERFORMED_BY = "Calibration performed by"


@dataclass(frozen=True, slots=True)
class Performer:
    """The account meta.json says the lab register authenticated at the run's start."""

    full_name: str
    account: str | None
    register: str | None
    authenticated_utc: str | None

    @classmethod
    def of(cls, meta: Mapping[str, object]) -> Performer | None:
        """None when meta.json names nobody (no account, or one without a name)."""
        found = meta.get("performer")
        if not isinstance(found, Mapping) or not found.get("full_name"):
            return None
        def text(key: str) -> str | None:     # as written; a non-text value as its text
            value = found.get(key)
            return None if value is None else str(value)

        return cls(str(found["full_name"]), text("account"), text("register"),
                   text("authenticated_utc"))


def performer(meta: Mapping[str, object]) -> tuple[str, str]:
    """(name as printed, how it is known)."""
    account = Performer.of(meta)
    if account is not None:
        how = (f"account {account.account}, authenticated by the lab register "
               f"{account.register} at {account.authenticated_utc}")
        return str(account.full_name), how
    who = meta.get("os_user") or meta.get("operator")
    return (f"{NOT_RECORDED}",
            "no account authenticated at the run's start (bench run --operator ACCOUNT)"
            + (f"; started by the operating-system user {who}" if who else ""))


def performer_line(meta: Mapping[str, object]) -> str:
    name, how = performer(meta)
    return f"{PERFORMED_BY}: {name} ({how})."


def equipment_lines(meta: Mapping[str, object], simulated: bool) -> list[str]:
    """Each item the register's inventory did not clear (a finding on twins; a real stand
    with one is not started) and each used under a recorded deviation."""
    where = meta.get("equipment_register")
    statuses = got if isinstance(got := meta.get("equipment_status"), list) else []
    if not where:
        return ["Equipment: no lab register was named (lab file register:), so the "
                "instruments were not checked against the lab's equipment inventory."]
    out = []
    for s in statuses:
        if not isinstance(s, Mapping):
            continue
        if s.get("problem"):
            out.append(f"Equipment: {s['problem']}" + (
                " A finding of a run on simulated twins: a real stand with it is not "
                "started." if simulated else ""))
        if s.get("deviation"):
            out.append(f"Equipment deviation: {s['deviation']}.")
    if not out:
        out.append(f"Equipment: every item with a serial or calibration was in the lab "
                   f"register's inventory ({where}) and within its calibration when the "
                   "run started.")
    return out
