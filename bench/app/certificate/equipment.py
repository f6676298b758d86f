"""The equipment a certificate's values rest on, computed once for the PDF and the DCC
(issue 43): every instrument and reference with its serial (read back, or stated), its
calibration certificate, issuer, due date, the quantity it traces and its status on the
date of the work, the counters' reference input as read back, and the findings on
identities (ISO/IEC 17025 6.4.13 a, 7.8.4.1 c).

The PDF's traceability table (build.py) and the DCC's measuringEquipments
(bench/app/dcc/used_methods.py) are both rendered from `equipment_list`, so one cannot
say what the other does not.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Mapping
from dataclasses import dataclass

from bench.core.config import Traced
from bench.core.events import SessionStarted
from bench.core.settings_codec import identities
from bench.core.traceability import (
    Identities,
    identity_problems,
    serial_of,
    traced_items,
    with_declared_serials,
)
from bench.report.certificate.parts import Sources, text_of
from bench.report.result_frame import at

NONE = "—"

#: stand roles that command the item and measure nothing a result rests on
COMMANDING_ROLES = ("drive",)


@dataclass(frozen=True)
class EquipmentRow:
    """One row of the traceability table, as printed (every field is the PDF's text)."""

    where: str              # the stand key: axes.outer.counter, traceability[0], ...
    item: str
    serial: str             # read back, "X (stated, not read back)", NONE REPORTED, ...
    certificate: str        # NONE when the stand states no calibration
    issuer: str
    due: str                # ISO date, or NONE
    traces: str
    status: str             # valid / PAST DUE / in-situ / NOT TRACEABLE / read back ...
    identity: str | None = None   # what the instrument reported when the run opened it
    past_due: bool = False


@dataclass(frozen=True)
class EquipmentList:
    """The rows, the notes under them and the identity findings, for one run."""

    rows: tuple[EquipmentRow, ...]
    notes: tuple[str, ...]
    identity_findings: tuple[str, ...]
    stated: bool            # the stand file states any instrument or reference at all

    @property
    def past_due(self) -> bool:
        return any(r.past_due for r in self.rows)


def work_date(src: Sources) -> dt.date | None:
    """The date the work started (what due dates are compared with)."""
    stamp = (src.frame.dates.started_utc
             or src.event_utc(SessionStarted)
             or src.meta.get("created_utc"))
    try:
        return dt.datetime.fromisoformat(str(stamp).replace("Z", "+00:00")).date()
    except (TypeError, ValueError):
        return None


def _reported(ids: Identities, t: Traced) -> str | None:
    """The identity the instrument at `t.where` reported in this run. An instrument at
    `axes.<axis>.<role>` reported under ids[axis][role]; one elsewhere (a platform's
    `gyros.x.dmm`) under its role, or `<gyro>-<role>`, on the table axis."""
    parts = t.where.split(".")
    if parts[0].startswith("traceability"):
        return None
    names = [parts[-1]] + ([f"{parts[-2]}-{parts[-1]}"] if len(parts) > 1 else [])
    axes = [parts[1]] if parts[0] == "axes" and len(parts) > 2 else list(ids)
    for axis in axes:
        roles = ids.get(axis)
        if roles is None:
            continue
        for role in names:
            if role in roles:
                return roles[role]
    return None


def _serial(ids: Identities, t: Traced) -> str:
    """The serial the instrument reported in this run (its identity), not the stand
    file's; a reference the bench does not read: the stand file's, said to be stated."""
    if t.where.startswith("traceability"):
        return f"{t.stated_serial} (stated, not read back)" if t.stated_serial else NONE
    ident = _reported(ids, t)
    if ident is None:
        return "not recorded"
    return serial_of(ident) or "NONE REPORTED"


def _unstated_status(src: Sources, t: Traced) -> str:
    """Without a stated calibration: what a result of this run rests on it, truthfully."""
    role = t.where.rsplit(".", 1)[-1]
    axis = t.where.split(".")[-2] if "." in t.where else ""
    # the kind's part (its pairs: a rate is measured by the counter and the FOG)
    pairs = at(src.walked, "axes", axis, "pairs") if axis else None
    if role in COMMANDING_ROLES and pairs is not None:
        return ("none needed: it commands the rate; every reported rate is measured by "
                "the counter and the FOG, none read from the drive")
    if role in COMMANDING_ROLES:
        return ("none stated: it commands the position; no reported value is read from it "
                "(its stated position tolerance enters the budget as a bound)")
    if role == "fog" and pairs:
        return ("in-situ calibration: scale k and bias w0 cross-calibrated against the "
                "counter for each +/- pair (docs/method.md A3, eq. 5-6), "
                "so its rates are traceable through the counter's time base")
    return "NOT TRACEABLE: no calibration certificate in the stand file, yet results rest on it"


def _reference_rows(src: Sources) -> list[EquipmentRow]:
    """Each counter's reference input as the counter read it back (the timebase every
    counted period rests on), beside what the stand file claims."""
    ids = src.frame.instruments
    stand_axes = src.stand_file.get("axes", {}) or {}
    rows = []
    for axis, roles in ids.items():
        ref = roles.get("counter_reference") if isinstance(roles, Mapping) else None
        if not ref:
            continue
        counter = (stand_axes.get(axis) or {}).get("counter") or {}
        claimed = counter.get("reference") if isinstance(counter, Mapping) else None
        rows.append(EquipmentRow(
            f"axes.{axis}.counter.reference", f"counter reference input ({axis})", NONE,
            NONE, NONE, NONE, "the counter's time base (the reference at its input, "
            "listed above where the stand file states it)",
            f"read back from the counter: {ref}"
            + (f"; the stand file states {claimed}" if claimed else ""), identity=str(ref)))
    return rows


def equipment_list(src: Sources) -> EquipmentList:
    """The run's equipment, as the certificate states it and the DCC carries it."""
    from bench.app.records.assurance_notes import certificate_notes  # 17025 7.7 status

    items = traced_items(src.stand_file)
    ids = with_declared_serials(identities(src.frame.instruments), src.stand_file)
    findings = tuple(identity_problems(ids)) if (ids or items) else ()
    on = work_date(src)
    kept = src.equipment_in_force
    rows: list[EquipmentRow] = []
    differ: list[str] = []
    for t in items:
        inv = kept.get(t.where)
        cert: str | None
        issuer: str | None
        due: dt.date | None
        if inv is not None:     # the lab register's calibration in force (issue 55)
            cert, issuer, due_text = inv["certificate"], inv["issuer"], inv["due"]
            due = dt.date.fromisoformat(due_text)
            if t.stated and (t.certificate, t.due) != (cert, due):
                differ.append(f"{t.item} ({t.where}): the stand file states "
                              f"{t.certificate}, due {t.due}; the inventory's calibration "
                              f"in force is {cert}, due {due_text}")
        else:
            cert, issuer, due = t.certificate, t.issuer, t.due
        late = bool((inv is not None or t.stated) and on is not None and due is not None
                    and on > due)
        if late:
            assert on is not None
            status = f"PAST DUE on the date of the work ({on.isoformat()})"
        elif inv is not None:
            status = ("valid on the work's date (lab inventory)" if on else
                      "validity not checked")
        elif t.stated:
            status = "valid on the work's date" if on else "validity not checked"
        else:
            status = _unstated_status(src, t)
        shown = inv is not None or t.stated
        rows.append(EquipmentRow(
            t.where, t.item, _serial(ids, t),
            text_of(cert) if shown else NONE, text_of(issuer) if shown else NONE,
            due.isoformat() if due else NONE,
            text_of(t.traces) if t.traces else NONE, status, _reported(ids, t), late))
    rows += _reference_rows(src)
    notes = (["Calibrations of items in the lab's inventory are the register's record in "
              f"force when the run started ({src.meta.get('equipment_register')}); the "
              "others from the stand file (its SHA-256 above). Due dates are compared with "
              "the date the work started."] if kept else
             ["From the stand file (its SHA-256 above). Due dates are compared with the date "
              "the work started."])
    notes += [f"The stand file disagrees with the inventory: {d}." for d in differ]
    if any(r.past_due for r in rows):
        notes.append("An instrument past its calibration due date was used: the run warned "
                     "at its start; results depending on it are not shown to be traceable.")
    notes += certificate_notes(src.run_path)
    return EquipmentList(tuple(rows), tuple(notes), findings, bool(items))


def identity_lines(found: EquipmentList, simulated: bool) -> list[str]:
    """The identity findings as the certificate's deviations and the DCC's statements
    state them: a real stand with one is not issued (`bench authorise` refuses it)."""
    tail = (" A finding of a run on simulated twins: a real stand with it is not issued."
            if simulated else
            " This draft cannot be issued until every item has its own identity.")
    return [f"Equipment identity (ISO/IEC 17025 6.4.13 a): {p}.{tail}"
            for p in found.identity_findings]
