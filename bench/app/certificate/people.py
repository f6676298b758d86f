"""The people and the equipment status behind a certificate, stated once for the PDF and
the DCC (issue 42): the performer is the account the lab register authenticated at the
run's start, never a name from a file; the signatory is the account it authenticated at
issue, with the signature's meaning; the equipment is as the register's inventory stood
when the run started."""

from __future__ import annotations

from bench.core.journal_codec import StartMeta
from bench.report.certificate.parts import NOT_RECORDED

PERFORMED_BY = "Calibration performed by"


def performer(meta: StartMeta) -> tuple[str, str]:
    """(name as printed, how it is known): the register's account when meta.json names
    one with a name, else who started the run, stated as not an authenticated person."""
    account = meta.performer
    if account is not None and account.full_name:
        how = (f"account {account.account}, authenticated by the lab register "
               f"{account.register} at {account.authenticated_utc}")
        return account.full_name, how
    who = meta.os_user or meta.operator
    return (f"{NOT_RECORDED}",
            "no account authenticated at the run's start (bench run --operator ACCOUNT)"
            + (f"; started by the operating-system user {who}" if who else ""))


def performer_line(meta: StartMeta) -> str:
    name, how = performer(meta)
    return f"{PERFORMED_BY}: {name} ({how})."


def equipment_lines(meta: StartMeta, simulated: bool) -> list[str]:
    """Each item the register's inventory did not clear (a finding on twins; a real stand
    with one is not started) and each used under a recorded deviation."""
    where = meta.equipment_register
    if not where:
        return ["Equipment: no lab register was named (lab file register:), so the "
                "instruments were not checked against the lab's equipment inventory."]
    out = []
    for s in meta.equipment_status:
        if s.problem:
            out.append(f"Equipment: {s.problem}" + (
                " A finding of a run on simulated twins: a real stand with it is not "
                "started." if simulated else ""))
        if s.deviation:
            out.append(f"Equipment deviation: {s.deviation}.")
    if not out:
        out.append(f"Equipment: every item with a serial or calibration was in the lab "
                   f"register's inventory ({where}) and within its calibration when the "
                   "run started.")
    return out
