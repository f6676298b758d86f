"""result.json (plus the run directory) -> the certificate's document model.

Every figure printed is taken from result.json; what the result lacks is taken from the
run directory's own records (meta.json, the copied stand and procedure files, the event
log, the raw files themselves) and never invented. Anything neither has is printed as
"not recorded", so a gap is visible to the reader instead of silently filled.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import hashlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import bench
from bench.analysis.coverage import COVERAGE_FORMULA, DOF_INFINITE
from bench.app.certificate import register
from bench.app.certificate.conditions import condition_rows
from bench.app.certificate.equipment import equipment_list, identity_lines
from bench.app.certificate.item import ItemRecord, item_record
from bench.app.certificate.item import decision_rule_text as agreed_rule_text
from bench.app.certificate.operator import prompt_blocks, software_note, utc_text
from bench.app.certificate.people import PERFORMED_BY, equipment_lines, performer, performer_line
from bench.app.certificate.register import Issue
from bench.core import events as ev
from bench.core import rundir_layout as layout
from bench.core.journal import sha256_file
from bench.core.registry import procedure_names
from bench.core.settings_codec import identities
from bench.core.traceability import with_declared_serials
from bench.kind import CertificatePart, installed
from bench.report.budget_codec import BudgetSite, budget_sites
from bench.report.certificate import methods
from bench.report.certificate.model import Block, Document, Fields, Para, Section, Signatures, Table
from bench.report.certificate.parts import (
    NOT_RECORDED,
    CertificateParts,
    Sources,
    label_of,
    num,
    rate_text,
    stand_of,
    text_of,
    verdict_label,
    vu_text,
)
from bench.report.certificate.rounding import (
    PERCENT,
    format_limit,
    format_sig,
    format_value_u,
    present,
    rel_unit,
)
from bench.report.corrections import statements as correction_statements
from bench.report.result_frame import (
    CertificateSettings,
    Check,
    HashedFile,
    Specification,
    Tolerance,
)

__all__ = ["NOT_RECORDED", "Sources", "build_document", "certificate_id", "decision_rule_text",
           "issued_number", "verdict_label"]

CAPABILITY_LIMIT = 0.3  # RMG 63-2003: the measurement's error limit <= 0.2-0.3 of the tolerance


def _trim(x: float) -> str:
    """A stated limit as written (1e-5 -> '0.00001'), no invented trailing zeros."""
    s = format_sig(x, 6)
    return s.rstrip("0").rstrip(".") if "." in s and "e" not in s else s


# -- the certificate id ----------------------------------------------------------------

DRAFT_PREFIX = "DRAFT"


def certificate_id(src: Sources) -> str:
    """The draft identifier of the run: `DRAFT-<date of completion>-<8 hex digits>`. Not a
    certificate number: only the lab register allocates those, at issue (issue 42), so a
    procedure file cannot name one and a copied run directory cannot issue one twice.

    The digits identify the run (its directory and creation time), so two runs never share
    an identifier. Without a run (a specimen) the digits are a digest of the results.
    """
    frame = src.frame
    run_dir = frame.run_dir or (src.run_path.name if src.run_path else None)
    created = frame.dates.created_utc or src.meta.get("created_utc")
    identity = (f"{run_dir}|{created}" if run_dir else
                json.dumps(src.result, sort_keys=True, default=str))
    digest = hashlib.sha256(identity.encode())
    stamp = frame.dates.completed_utc or src.meta.get("created_utc")
    day = ""
    if stamp:
        try:
            day = dt.datetime.fromisoformat(str(stamp).replace("Z", "+00:00")).strftime("%Y%m%d")
        except ValueError:
            day = ""
    return "-".join(p for p in (DRAFT_PREFIX, day, digest.hexdigest()[:8].upper()) if p)


def issued_number(src: Sources) -> str:
    """The number of the run's latest issue (what the PDF beside it carries); the base
    number when nothing was issued yet. For other forms of the same certificate (DCC)."""
    done = register.issues(src.run_path)
    return done[-1].number if done else certificate_id(src)


def _cert(src: Sources, issue: Issue | None = None) -> CertificateSettings:
    """The certificate settings: the procedure's `certificate:` block over the lab's file;
    on an issued certificate the issuer's identity is the lab register's (issue 54)."""
    cert = src.frame.certificate or src.procedure_file.get("certificate", {}) or {}
    return CertificateSettings.of(cert, issue.issuer if issue is not None else ())


# -- the document --------------------------------------------------------------------------

AUTHORITATIVE = ("The PDF file certificate.pdf is the authoritative form of this certificate; "
                 "the HTML rendering carries the same content for reading on screen.")
SIMULATED_MARK = "SIMULATED RUN: NOT A CALIBRATION"
DRAFT_MARK = "DRAFT, NOT AUTHORISED"


#: a section from outside the run directory (the records' history): title and blocks
ExtraSection = tuple[str, tuple[Block, ...]]

#: what a procedure kind that says nothing of itself (or none installed) answers
NEUTRAL = CertificateParts()


@dataclass(frozen=True)
class Procedure:
    """The run's procedure kind, as the certificate sees it: its name and its answers."""

    name: str
    parts: CertificatePart

    @property
    def title(self) -> str:
        return self.parts.certificate_procedure_name or self.name

    def quantity(self, key: str | None, default: str | None = None) -> str:
        """A checked quantity in words."""
        key = str(key)
        return self.parts.certificate_quantities.get(
            key, label_of(key) if default is None else default)


def procedure_of(src: Sources) -> Procedure:
    """The kind the result names; for an older result that names none, the installed
    kind that recognises its keys (bench/core/registry.py: kinds are found by entry point)."""
    name = str(src.frame.procedure or src.procedure_file.get("procedure") or "")
    if not name:
        name = next((n for n in procedure_names() if _parts(n).certificate_recognises(src)),
                    "")
    return Procedure(name, _parts(name))


def _parts(name: str) -> CertificatePart:
    kind = installed(name)
    return kind.certificate if kind is not None else NEUTRAL


def build_document(src: Sources, issued: dt.date | None = None, issue: Issue | None = None,
                   extra_sections: Sequence[ExtraSection] = ()) -> Document:
    """The certificate of the decoded run (`Sources.load`) for one issue; without `issue`
    (or with an unauthorised one) the DRAFT of the run's next revision: marked DRAFT, NOT
    AUTHORISED on every page, no date of issue, no authorisation claimed. `issued` is kept
    for callers that dated drafts."""
    cid = certificate_id(src)
    if issue is None:
        issue = register.draft(src.run_path, cid)
    proc = procedure_of(src)
    cert = _cert(src, issue)
    lab = str(cert.laboratory or "Calibration laboratory (name not given)")
    checks = _checks(src, proc)
    sections: list[Section] = []
    n = _Counter()
    sections.append(Section(n.next(), "Identification", _identification(src, issue,
                                                                       proc, checks)))
    sections.append(Section(n.next(), "Item calibrated and measuring instruments",
                            _instruments(src, proc)))
    sections.append(Section(n.next(), "Method", _method(src, proc)))
    sections.append(Section(n.next(), "Deviations", _deviations(src, proc)))
    fixes = correction_statements(src.frame.corrections)    # issue 58: a corrected re-issue says so
    if fixes:
        sections.append(Section(n.next(), "Corrections applied",
                                tuple(Para(t) for t in fixes)))
    sections.append(Section(n.next(), "Conditions", _conditions(src)))
    sections += proc.parts.certificate_sections(src, n.next(), checks)
    sections.append(Section(n.next(), "Conformity", _conformity(src, checks, proc)))
    sections.append(Section(n.next(), "Records: raw data and inputs", _records(src)))
    for title, blocks in [*proc.parts.certificate_annexes(src), *extra_sections]:
        sections.append(Section(n.next(), title, tuple(blocks)))
    budgets = budget_tables(budget_sites(src.walked))
    if budgets:
        sections.append(Section(n.next(), "Uncertainty budgets (EA-4/02)", budgets,
                                new_page=True))
    statements = proc.parts.certificate_statements(methods.STATEMENTS)
    statements.append(AUTHORITATIVE)
    sections.append(Section(n.next(), "Statements", tuple(Para(t) for t in statements)))
    sections.append(Section(n.next(), "Authorisation", _signatures(src, issue)))
    item, serial = proc.parts.certificate_item(src)
    subtitle = f"{item}, serial {serial}"
    simulated = bool(stand_of(src).simulated)
    if simulated:
        subtitle += " (SIMULATED stand)"
    marks = [m for m in (DRAFT_MARK if issue.draft else "",
                         SIMULATED_MARK if simulated else "") if m]
    return Document(
        cert_id=issue.number,
        title="Calibration certificate",
        subtitle=subtitle,
        laboratory=lab,
        issue_date=issue.issue_date if not issue.draft else "",
        verdict=_verdict(src),
        sections=tuple(sections),
        footer="This certificate shall not be reproduced except in full without the written "
               "approval of the issuing laboratory. " + AUTHORITATIVE.split(";")[0] + ".",
        meta={"run_title": str(src.frame.title or src.procedure_file.get("title") or ""),
              "procedure": proc.name, "revision": str(issue.revision),
              "replaces": "" if issue.draft else issue.replaces or "", "scope": _scope_line(src, checks, proc)},
        watermark=" / ".join(marks),
    )


def _g(x: float | None, sig: int = 3) -> str:
    if x is None:
        return "—"
    return format_sig(x, sig) if x != 0 else "0"


def budget_tables(sites: Sequence[BudgetSite]) -> tuple[Block, ...]:
    """One table per budget in result.json (bench.report.budget_codec), in EA-4/02's
    columns."""
    if not sites:
        return ()
    blocks: list[Block] = [Para(
        "Each budget (EA-4/02 M:2022 section 4): input quantity X_i, estimate x_i, standard "
        "uncertainty u(x_i), distribution, sensitivity coefficient c_i, contribution "
        "u_i(y) = |c_i|·u(x_i) (u(x_i) in the estimate's unit) and degrees of freedom ν_i (∞: Type B or very many samples); "
        "correlated inputs are named under their budget with r (GUM 5.2.2); "
        "then, by the one rule of docs/method.md D1 that the analysis computes with: "
        + COVERAGE_FORMULA + ". Values are in the units named (1: a plain fraction, "
        "1e-6 = 1 ppm). Each budget is checked against the U reported with the result.",
        "note")]
    for where, _owner, b in sites:
        un = "" if b.unit == "1" else f" {b.unit}"
        # the input's unit beside its estimate (u(x_i) is in the same unit)
        rows = tuple((t.quantity, _g(t.estimate, 6) + ("" if t.unit in ("", "1")
                                                       else f" {t.unit}"),
                      _g(t.ustd), t.distribution,
                      _g(t.sensitivity), _g(t.contribution),
                      "∞" if t.dof is None or t.dof > 1e4 else f"{t.dof:.0f}")
                     for t in b.terms)
        nu = b.dof_eff
        agree = b.reproduces
        notes = [f"u_c = {_g(b.ustd)}{un}; ν_eff = "
                 f"{'∞' if nu is None or nu > DOF_INFINITE else f'{nu:.1f}'}; "
                 f"k = {b.k:.2f}; U = {_g(b.U, 2)}{un}" +
                 ("" if b.reported_U is None else
                  f"; U reported with the result {_g(b.reported_U, 2)}{un} "
                  + ("(reproduced)" if agree else "(NOT reproduced by this budget)"))]
        for i, j, r in b.correlations:
            # u_c^2 gains 2 c_i c_j u(x_i) u(x_j) r (GUM 5.2.2, docs/method.md D1)
            notes.append(f"Correlated inputs: r(row {i + 1}, row {j + 1}) = {r:g}; u_c² = "
                         "Σ (c_i·u(x_i))² + 2 Σ r·c_i·u(x_i)·c_j·u(x_j) (GUM 5.2.2).")
        if b.note:
            notes.append(b.note)
        blocks.append(Table(("Quantity X_i", "Estimate x_i", "u(x_i)", "Distribution",
                             "c_i", "u_i(y)", "ν_i"), rows,
                            widths=(3.4, 1.3, 1.0, 1.2, 1.0, 1.0, 0.6), align="lrrlrrr",
                            caption=f"{b.quantity}, {where}: estimate "
                                    f"{_g(b.estimate, 6)}{un}", notes=tuple(notes)))
    return tuple(blocks)


class _Counter:
    def __init__(self) -> None:
        self.i = 0

    def next(self) -> str:
        self.i += 1
        return str(self.i)


def _checks(src: Sources, proc: Procedure) -> list[Check]:
    """The engine's checks[]; without it, what the kind reads from its own results."""
    if isinstance(src.frame.get("checks"), list):
        return list(src.frame.checks)
    return proc.parts.certificate_checks(src)


def _identification(src: Sources, issue: Issue, proc: Procedure,
                    checks: list[Check]) -> tuple[Block, ...]:
    stand = stand_of(src)
    cert = _cert(src, issue)
    dates = src.frame.dates
    started = dates.started_utc or src.event_utc(ev.SessionStarted)
    completed = dates.completed_utc or src.event_utc(ev.Completed, last=True)
    item, serial = proc.parts.certificate_item(src)
    rows: list[tuple[str, str]] = [
        (("Draft identifier (the lab register allocates the certificate number at issue)",
          issue.number) if issue.draft else ("Certificate number", issue.number)),
        ("Revision", _revision_text(issue)),
        ("Title of the work", text_of(src.frame.title or src.procedure_file.get("title"))),
        ("Issued by", text_of(cert.laboratory)),
        ("Laboratory address", text_of(cert.address)),
    ]
    if cert.accreditation:
        rows.append(("Accreditation", text_of(cert.accreditation)))
    rows += [
        ("Customer", text_of(cert.customer)),
        ("Customer address", text_of(cert.customer_address)),
        ("Customer contact", text_of(cert.customer_contact)),
        ("Item calibrated", item),
        ("Serial number", serial),
        *proc.parts.certificate_identification(src),
    ]
    site = cert.site or stand.location
    rows.append(("Site of calibration", text_of(site)))
    if stand.simulated:
        rows.append(("Nature of the work", "SIMULATED run (instrument twins on real channels): "
                     "these results describe no physical item; every page is marked"))
    rows += [
        ("Procedure", proc.title),
        ("Work started", utc_text(started)),
        ("Work ended", (utc_text(completed) + _how_ended(src)) if completed
         else "not completed"),
        ("Date of issue (authorisation)", "none: DRAFT, NOT AUTHORISED" if issue.draft
         else issue.issue_date),
        ("Statement of conformity", _overall(src, checks, proc)),
    ]
    skip = {"laboratory", "customer", "number", "id", "certificate_id", "prefix", "signers",
            "signatories", "address", "accreditation", "customer_address", "customer_contact",
            "site", "lab", "authoritative", "specification", "location", "email", "phone",
            "code", "country_code", "performance_location", "signing", "require_signed_dcc",
            "records", "recertification", "responsible_persons"}
    rows += [(label_of(k), text_of(v)) for k, v in cert.entries if k not in skip]
    blocks: list[Block] = [Fields(tuple(rows))]
    run_dir = src.frame.run_dir or (src.run_path.name if src.run_path else NOT_RECORDED)
    blocks.append(software_note(src.meta.get("bench_version"), src.events, bench.__version__, str(run_dir)))
    blocks.append(Para(AUTHORITATIVE, "note"))
    return tuple(blocks)


def check_class(c: Check) -> str:
    """'consistency' (physics cross-check, not conformity), 'not-assessed' (excluded from
    conformity, e.g. a σ at the timing floor), or 'conformity'."""
    if c.rule == "consistency":
        return "consistency"
    if c.verdict == "not-assessed":
        return "not-assessed"
    return "conformity"


def _coverage(checks: list[Check], proc: Procedure
              ) -> tuple[list[str], list[str], int]:
    """(quantities the verdict covers, quantities not assessed, checks excluded)."""
    conf = [c for c in checks if check_class(c) == "conformity"]
    covered = list(dict.fromkeys(str(c.quantity) for c in conf))
    names = [proc.quantity(q) for q in covered]
    not_assessed = [text for key, text in proc.parts.certificate_measured
                    if key not in covered]
    excluded = sum(1 for c in checks if check_class(c) == "not-assessed")
    return names, not_assessed, excluded


def _scope_line(src: Sources, checks: list[Check], proc: Procedure) -> str:
    names, not_assessed, excluded = _coverage(checks, proc)
    if not names:
        return "No statement of conformity: the procedure states no tolerances."
    text = "The verdict covers: " + ", ".join(names) + "."
    if excluded:
        text += f" {excluded} check(s) could not be assessed (section Conformity)."
    if not_assessed:
        text += " Not assessed: " + ", ".join(not_assessed) + "."
    return text


def _overall(src: Sources, checks: list[Check], proc: Procedure) -> str:
    verdict = _verdict(src).lower()
    conf = [c for c in checks if check_class(c) == "conformity"]
    failed = [c for c in conf if (c.verdict or "").lower() != "pass"]
    cons = [c for c in checks if check_class(c) == "consistency"]
    rule = _rule_name(src.frame.decision_rule)
    scope = _scope_line(src, checks, proc)
    cons_text = ""
    if cons:
        bad = sum(1 for c in cons if str(c.verdict).lower() != "pass")
        cons_text = (f" Consistency checks (not conformity): {len(cons) - bad} of {len(cons)} "
                     "consistent" + (", the measurement is in doubt" if bad else "") + ".")
    if verdict == "incomplete":
        return ("INCOMPLETE: the run did not complete every step; no statement of conformity is "
                "made for the points not measured." + cons_text)
    excluded = sum(1 for c in checks if check_class(c) == "not-assessed")
    if not conf and excluded:
        return (f"NO STATEMENT OF CONFORMITY: none of the {excluded} check(s) could be "
                "assessed (section Conformity)." + cons_text)
    if not conf:
        return (f"{verdict.upper()}: no conformity check was made (the procedure states no "
                "tolerances)." + cons_text)
    if not failed:
        head = (f"PASS: all {len(conf)} conformity checks met the specification under the "
                f"{rule} decision rule (section Conformity).")
    else:
        head = (f"FAIL: {len(failed)} of {len(conf)} conformity checks did not meet the "
                f"specification under the {rule} decision rule (section Conformity).")
    return f"{head} {scope}{cons_text}"


def _verdict(src: Sources) -> str:
    """The run's verdict as result.json states it; a result that states none is incomplete."""
    verdict = src.frame.verdict
    return "incomplete" if verdict is None else verdict


def _rule_name(rule: str | None) -> str:
    return {"guard-band": "guard-band (guarded acceptance, w = U)",
            "simple": "simple acceptance"}.get(str(rule or "simple"), str(rule))


def _instruments(src: Sources, proc: Procedure) -> tuple[Block, ...]:
    stand = stand_of(src)
    item, serial = proc.parts.certificate_item(src)
    what = proc.parts.certificate_stand_label
    blocks: list[Block] = [Fields((
        ("Item calibrated", f"{item}, serial {serial}"),
        (what, f"{text_of(stand.maker)} {text_of(stand.model)}, serial "
               f"{text_of(stand.serial)}"),
        ("Stand file", f"{text_of(stand.file or src.meta.get('stand_file'))}"),
        ("Stand file SHA-256", text_of(stand.sha256 or src.meta.get("stand_sha256"))),
    ))]
    ids = with_declared_serials(identities(src.frame.instruments), src.stand_file)
    if not ids:  # the event log records each axis's identities at the start of a session
        for e in ev.of_kind(src.events, ev.Identity):
            ids.setdefault(e.axis, {}).update(e.instruments)
    stand_axes = src.stand_file.get("axes", {}) or {}
    rows = []
    for axis in dict.fromkeys([*ids, *stand_axes]):
        roles = dict.fromkeys([*(ids.get(axis) or {}), *(stand_axes.get(axis) or {})])
        for role in roles:
            if role == "counter_reference":
                continue   # in the traceability table
            ident = (ids.get(axis) or {}).get(role)
            conf = (stand_axes.get(axis) or {}).get(role) or {}
            conf = {k: v for k, v in conf.items() if k != "calibration"} \
                if isinstance(conf, Mapping) else conf
            setting = text_of(conf) if conf else ""
            text = text_of(ident) if ident else "identity not recorded"
            if role == "fog" and ident and "(?IS)" not in str(ident):
                text = ("as configured in the stand file (this FOG was not asked its serial, "
                        "?IS): " + text)
            rows.append((axis, role, text, setting or "—"))
    if rows and all(r[3] == "—" for r in rows):
        blocks.append(Table(("Axis", "Instrument", "Identity (as reported)"),
                            tuple(r[:3] for r in rows), widths=(0.9, 1.0, 5.0), align="lll",
                            caption="Instruments used, with the identity each reported "
                                    "(*IDN?, drive identity objects, FOG model)"))
    elif rows:
        blocks.append(Table(("Axis", "Instrument", "Identity (as reported)", "Settings"),
                            tuple(rows), widths=(0.9, 1.0, 3.2, 3.6), align="llll",
                            caption="Instruments used, with the identity each reported "
                                    "(*IDN?, drive identity objects, FOG model)"))
    else:
        blocks.append(Para("Instrument identities: not recorded.", "note"))
    record = item_record(src)
    if record.readback:
        # every setting that differs from its read-back, and on twins why, once
        blocks.append(Para("Settings that differ from their read-back: "
                           + "; ".join(x for x in record.readback if not x.startswith("On "))
                           + ". " + " ".join(x for x in record.readback if x.startswith("On ")),
                           "note"))
    blocks += _shared_identities(rows)
    blocks += _item_blocks(record, proc)
    blocks += _traceability(src)
    return tuple(blocks)


def _item_blocks(record: ItemRecord, proc: Procedure) -> list[Block]:
    """The item as received and as left (ISO/IEC 17025 7.8.2.1 g, 7.8.4.1 b), and the
    linked as-found run's checks (bench/app/certificate/item.py; the DCC states the same)."""
    blocks: list[Block] = [Fields(record.rows)]
    found = record.as_found
    if found is not None and found.found and found.checks:
        rows = []
        for c in found.checks:
            vu, tol = _check_texts(c, proc)
            rate = num(c.set_rate_dps)
            rows.append((text_of(c.axis), rate_text(rate) if rate is not None else "—",
                         proc.quantity(c.quantity), vu, tol,
                         verdict_label(c.verdict, c.rule or "")))
        blocks.append(Table(("Axis", "Set rate, °/s", "Quantity", "Value ± U", "Tolerance T",
                             "Verdict"), tuple(rows), widths=(0.8, 1.0, 2.2, 2.0, 1.3, 1.4),
                            align="lrlrrc",
                            caption=f"As found: the checks of run {found.run_id}, before the "
                                    "adjustments"))
    return blocks


def _shared_identities(rows: list[tuple[str, str, str, str]]) -> list[Block]:
    """Two instruments of one kind answering with one identity (maker, model, serial) are
    either one instrument or misreporting: the reader must be told."""
    seen: dict[tuple[str, str], list[str]] = {}
    for axis, role, ident, _ in rows:
        if role in ("counter", "drive") and ident and not ident.startswith("identity not"):
            seen.setdefault((role, ident), []).append(axis)
    return [Para(f"CHECK: the {role}s of axes {', '.join(axes)} report the same identity "
                 f"({ident}); two instruments cannot share a serial number. On a simulated "
                 "bench the twins answer their model's default identity.", "strong")
            for (role, ident), axes in seen.items() if len(axes) > 1]


def _traceability(src: Sources) -> tuple[Block, ...]:
    """Where each measured quantity's traceability to the SI comes from (17025 7.8.4.1 c):
    the rows of `equipment_list` (the DCC's measuringEquipments carry the same rows)."""
    found = equipment_list(src)
    if not found.stated:
        return (Para("Metrological traceability: the stand file states no calibration "
                     "certificates; NOT SHOWN for any instrument.", "strong"),)
    rows = tuple((r.item, r.serial, r.certificate, r.issuer, r.due, r.traces, r.status)
                 for r in found.rows)
    return (Table(("Item", "Serial (read back)", "Certificate", "Issued by", "Due",
                   "Quantity traced", "Status"), rows,
                  widths=(1.7, 1.3, 1.7, 1.4, 1.1, 1.9, 2.2),
                  align="lllllll", caption="Metrological traceability: calibration of the "
                  "instruments and references used", notes=found.notes),)


def _method(src: Sources, proc: Procedure) -> tuple[Block, ...]:
    pf = src.frame.procedure_file
    name = pf.name or src.meta.get("procedure_name")
    sha = pf.sha256 or src.meta.get("procedure_sha256")
    blocks: list[Block] = list(proc.parts.certificate_method(src))
    method = src.frame.method
    rows = [("Procedure file", text_of(name)), ("Procedure file SHA-256", text_of(sha))]
    rows += [(label_of(k), text_of(v)) for k, v in method.items()
             if k not in ("decision_rule", "tolerance", "turns_per_axis")]
    rows.append(("Decision rule", _rule_name(src.frame.decision_rule)))
    ident = proc.parts.certificate_procedure_id
    if ident is not None:
        code, part, paper = ident
        version = str(src.meta.get("bench_version") or bench.__version__)
        rows += [("Procedure ID and revision", f"{code}, revision {version} (ratebench "
                  f"{version}; method: docs/method.md part {part}, shipped as "
                  f"bench/method.md{_method_digest()})"),
                 (f"Reference [{part}]", paper),
                 ("Validation", methods.VALIDATION)]
    blocks.append(Fields(tuple(rows)))
    return tuple(blocks)


def _method_digest() -> str:
    """The method document this release ships, by its SHA-256 (what the revision means)."""
    path = Path(bench.__file__).parent / "method.md"
    return f", SHA-256 {sha256_file(path)[:16]}…" if path.is_file() else ""


def _how_ended(src: Sources) -> str:
    """How the run ended beside "Work ended": its last session's ending (a resume is a
    session of the same run), nothing for a run that completed."""
    ended = src.frame.ended
    if ended is not None and ended != "completed":
        return f" ({ended})"
    return " (aborted)" if src.frame.aborted and ended is None else ""


def _ended_word(src: Sources) -> str:
    return {"killed or crashed": "was killed or crashed", "refused": "was refused"}.get(
        src.frame.ended or "", "was aborted")


def _session_lines(src: Sources) -> str:
    """' Sessions: 1 from ... to ... UTC (aborted; performer ...); 2 ...' from result.json's
    `run_sessions` (empty for a result written before it was kept)."""
    parts = []
    for x in src.frame.run_sessions:
        by = (f"performer {x.performer}" if x.performer else
              f"performer not recorded (OS user {x.os_user or 'unknown'})")
        end = utc_text(x.ended_utc) if x.ended_utc else "no end written"
        parts.append(f"session {x.session} from {utc_text(x.started_utc)} to "
                     f"{end} ({x.ended or 'running'}; {by})")
    return " Sessions: " + "; ".join(parts) + "." if parts else ""


def _deviations(src: Sources, proc: Procedure) -> tuple[Block, ...]:
    blocks: list[Block] = list(proc.parts.certificate_method_deviations(src))
    run: list[str] = []
    sessions = src.frame.sessions
    if sessions is not None and sessions > 1:
        run.append(f"The run was interrupted and resumed: it ran in {sessions} sessions. Each "
                   "unit (a ± pair) was measured whole within one session."
                   + _session_lines(src))
    if src.frame.aborted:
        run.append(f"The run {_ended_word(src)} before every step was done; the points not "
                   "measured are absent from the results.")
    if src.frame.verdict == "incomplete":
        run.append("The result is incomplete: no statement of conformity is made for the "
                   "missing points.")
    for d in src.frame.deviations:
        run.append(text_of(d))
    for e in ev.of_kind(src.events, ev.IdentityMismatch):  # twins only: a real stand is refused
        run.append(f"Identity: {text_of(e.where)}: the stand file states serial "
                   f"{text_of(e.stated)}, the instrument reported "
                   f"{text_of(e.reported)} ({text_of(e.query)}); its check "
                   "values are filed under the reported serial. A finding of a run on "
                   "simulated twins: a real stand with this mismatch is refused.")
    run += equipment_lines(src.start, bool(stand_of(src).simulated))
    run += identity_lines(equipment_list(src), bool(stand_of(src).simulated))
    for where in src.dropped:
        run.append(f"result.json: {where} was malformed and is not reported here.")
    run += proc.parts.certificate_run_deviations(src)
    blocks.append(Para("From the procedure, in this run:", "strong"))
    blocks += [Para(f"• {t}") for t in run] or [Para("None.")]
    return tuple(blocks)


def _measured_conditions(src: Sources) -> list[Block]:
    """What the bench measured itself: the FOG's temperature per half (procedures that
    record it, `conditions_measured`); the room: not measured unless a sensor says so."""
    blocks: list[Block] = []
    fog = src.frame.conditions_measured.fog_halves
    if fog is not None:
        rows = []
        for axis, halves in fog.items():
            for h in halves:
                half = num(h.half)
                rows.append((axis, rate_text(h.set_rate_dps),
                             "—" if half is None else str(int(half) + 1),
                             _g(h.min_c, 4), _g(h.mean_c, 4), _g(h.max_c, 4)))
        blocks.append(Table(("Axis", "Set rate, °/s", "Half", "Min, °C", "Mean, °C",
                             "Max, °C"), tuple(rows), align="lrrrrr",
                            caption="Measured: temperature of the FOG on the table top, per "
                                    "half, from its frames (integer °C resolution); the "
                                    "temperature of the item's table top, not of the room"))
    return blocks


def _conditions(src: Sources) -> tuple[Block, ...]:
    """Each condition as what it is (bench/app/certificate/conditions.py, which the DCC's
    influenceConditions share): nominal from the procedure file, measured where the run
    measured it, "not measured" where nothing did; one mains frequency for the run."""
    rows = condition_rows(src)
    cond = src.frame.conditions or src.procedure_file.get("conditions") or {}
    blocks: list[Block] = [Table(
        ("Condition", "Nominal (procedure file)", "Measured in this run"),
        tuple((r.condition, r.nominal, r.measured) for r in rows),
        widths=(2.2, 2.4, 4.0), align="lll",
        caption="Conditions: the nominal values stated, and what this run measured",
        notes=("Nominal: the laboratory's conditions as the procedure file states them, "
               "not measured during this run. Measured: by the bench's own instruments "
               "during this run; 'not measured' where none of them measured it.",)
        if cond else ("No nominal conditions were stated in the procedure file.",))]
    blocks += _measured_conditions(src)
    blocks += prompt_blocks(src.events)
    return tuple(blocks)


# -- conformity, records, signatures -------------------------------------------------------

def decision_rule_text(rule: str) -> str:
    if rule == "guard-band":
        return ("Decision rule: guarded acceptance with a guard band equal to U (ILAC-G8:09/2019 "
                "§4.2.2). A check PASSES when |value| + U ≤ T and FAILS when |value| > T. When "
                "|value| ≤ T < |value| + U the measured value is inside the tolerance but within "
                "U of its limit, so conformity is not shown: this is stated as FAIL (guard "
                "band). For σ the guard is its one-sided 97.5 % upper limit (chi-square with "
                "N − 1 degrees of freedom) in place of |value| + U. Risk: the probability of a "
                "false accept is at most about 2.5 % where the value's distribution is normal "
                "(the rate error: a mean of N turns with the small-sample factor of section 3) "
                "or, for σ, where the per-turn rates are normal; it is not claimed for other "
                "distributions.")
    return ("Decision rule: simple acceptance (ILAC-G8:09/2019 §4.2.1, shared risk). A check "
            "PASSES when |value| ≤ T and FAILS when |value| > T; U is reported but not used in "
            "the decision. For a value close to the limit the probability of a false accept "
            "may approach 50 %; the capability column shows where U is small enough for this "
            "rule to be sound.")


ABSOLUTE_UNITS = {"dph": "°/h", "dps": "°/s", "deg": "°", "arcmin": "arcmin", "s": "s"}


@dataclass(frozen=True)
class CheckRow:
    """One check, whatever its unit: relative (`value_rel`) or absolute (`value_dph`...)."""

    value: float | None
    u: float | None
    tolerance: float | None
    expected: float | None
    suffix: str            # rel, dph, dps, deg...

    @classmethod
    def of(cls, c: Check) -> CheckRow:
        for suffix in ("rel", *ABSOLUTE_UNITS):
            if c.states(f"value_{suffix}"):
                return cls(c.figure(f"value_{suffix}"), c.figure(f"u_{suffix}"),
                           c.figure(f"tolerance_{suffix}"), c.figure(f"expected_{suffix}"),
                           suffix)
        return cls(None, None, None, None, "rel")

    def texts(self, signed: bool) -> tuple[str, str]:
        """(value ± U, tolerance or expected value) in the check's unit."""
        if self.suffix == "rel":
            unit = rel_unit(self.value, self.u, self.tolerance)
            vu = f"{vu_text(self.value, self.u, unit, signed)} {unit.name}"
            tol = f"{_trim(self.tolerance * unit.scale)} {unit.name}" if self.tolerance else "—"
            return vu, tol
        name = ABSOLUTE_UNITS[self.suffix]
        vu = f"{vu_text(self.value, self.u, None, signed)} {name}"
        if self.tolerance:
            return vu, f"{_trim(self.tolerance)} {name}"
        if self.expected is not None:
            return vu, f"expected {format_value_u(self.expected, self.u).value} {name}"
        return vu, "—"


def _specification(src: Sources, proc: Procedure) -> list[Block]:
    spec = (src.frame.specification
            or Specification.of(src.procedure_file.get("specification")))
    if spec is None or not spec.source:
        return [Para("Specification: NOT IDENTIFIED. The procedure file names no source for "
                     "its tolerances (key specification.source); the checks below compare "
                     "with the procedure's numbers only.", "strong")]
    rows = [("Specification", text_of(spec.source))]
    for key, text in spec.definitions.items():
        name = proc.quantity(key, proc.quantity(str(key).rsplit("_", 1)[0], label_of(key)))
        rows.append((f"Definition: {name}", text_of(text)))
    return [Fields(tuple(rows))]


def _check_texts(c: Check, proc: Procedure) -> tuple[str, str]:
    """(value as printed, tolerance) of one check under docs/method.md D2: '< L' for an
    unresolved value, its interval for an asymmetric one, else 'value ± U' (the conformity
    table and the as-found table print checks alike)."""
    row = CheckRow.of(c)
    vu, tol_text = row.texts(str(c.quantity) not in proc.parts.certificate_unsigned)
    if check_class(c) == "not-assessed" or c.one_sided:
        # an unresolved value is stated as '< L' and judged on L (bench.report.conformity)
        unit = rel_unit(row.value, row.tolerance)
        limit = num(c.upper_rel)
        vu = present(row.value, row.u, unit.scale, resolved=False,
                     upper=limit).with_unit(unit.name) + f" ({c.floor_name or 'timing floor'})"
    elif (upper_rel := num(c.upper_rel)) is not None and row.suffix == "rel":
        unit = rel_unit(row.value, row.u, row.tolerance)
        lower_rel = num(c.lower_rel)
        if lower_rel is not None and row.value is not None:
            # docs/method.md D2: an asymmetric interval is printed as its interval
            vu = present(row.value, None, unit.scale, resolved=True,
                         interval=(lower_rel, upper_rel)).with_unit(unit.name)
        else:
            vu += f"; 97.5 % limit {format_limit(upper_rel * unit.scale)[0]}"
    return vu, tol_text


def _conformity(src: Sources, checks: list[Check], proc: Procedure
                ) -> tuple[Block, ...]:
    rule = str(src.frame.decision_rule or (checks[0].rule if checks else "simple"))
    blocks: list[Block] = [*_specification(src, proc), Para(decision_rule_text(rule)),
                         Para("Decision rule: " + agreed_rule_text(src) + " (ISO/IEC 17025 "
                              "7.1.3).")]
    blocks.append(Para("Scope. " + _scope_line(src, checks, proc)))
    blocks.append(Para(
        "Measurement capability (RMG 63-2003): the expanded uncertainty of a check should not "
        f"exceed 0.2-0.3 of its tolerance; a ratio U/T ≤ {CAPABILITY_LIMIT:g} is marked met."))
    tol = src.frame.method.get("tolerance") or src.procedure_file.get("tolerance")
    if isinstance(tol, Mapping) and tol:
        table = _tolerance_table(Tolerance.all_of(dict(tol)), proc)
        if table.rows:
            blocks.append(table)
    if not checks:
        blocks.append(Para("The procedure states no tolerances: no conformity checks were "
                           "made and no statement of conformity is given for individual "
                           "values."))
        return tuple(blocks)
    consistency = [c for c in checks if check_class(c) == "consistency"]
    checks = [c for c in checks if check_class(c) != "consistency"]
    with_rate = all(num(c.set_rate_dps) is not None for c in checks)
    rows: list[tuple[str, ...]] = []
    notes: list[str] = []
    for i, c in enumerate(checks, start=1):
        row = CheckRow.of(c)
        ratio = num(c.capability_ratio)
        if ratio is None and row.u is not None and row.tolerance:
            ratio = row.u / row.tolerance
        ok = c.capability_ok
        if ok is None and ratio is not None:
            ok = ratio <= CAPABILITY_LIMIT
        if row.u is None or row.u <= 0:
            cap = "no U stated"  # a ratio of 0 would claim a capability nobody showed
        elif ratio is None:
            cap = "—"
        else:
            cap = f"{format_sig(ratio, 2)} " + ("met" if ok else "not met")
        inside = (row.value is not None and row.tolerance is not None
                  and abs(row.value) <= row.tolerance)
        label = verdict_label(c.verdict, c.rule or rule, inside)
        quantity = proc.quantity(c.quantity)
        vu, tol_text = _check_texts(c, proc)
        if check_class(c) == "not-assessed" or c.one_sided:
            cap = "—"
        rate = num(c.set_rate_dps)
        point = rate_text(rate) if with_rate else (f"{rate_text(rate)} °/s" if rate is not None else "—")
        rows.append((str(i), text_of(c.axis), point, quantity, vu, tol_text, cap, label))
        if label != "PASS" and c.reason:
            notes.append(f"Check {i}: {label}: {c.reason}")
        elif label != "PASS":
            notes.append(f"Check {i}: {label}.")
    header = ["#", "Axis", "Set rate, °/s" if with_rate else "Point", "Quantity", "Value ± U",
              "Tolerance T", "U/T (RMG 63)", "Verdict"]
    widths = [0.4, 0.8, 1.0, 2.2, 1.9, 1.3, 1.2, 1.4]
    align = "rlrlrrcc"
    if all(r[2] == "—" for r in rows):  # no check is tied to a rate
        rows = [r[:2] + r[3:] for r in rows]
        del header[2], widths[2]
        align = align[:2] + align[3:]
    if rows:
        blocks.append(Table(tuple(header), tuple(rows), widths=tuple(widths), align=align,
                            caption="Conformity with the specification's tolerances",
                            notes=tuple(notes)))
    if consistency:
        blocks.append(_consistency_table(consistency, proc))
    return tuple(blocks)


def _consistency_table(checks: list[Check], proc: Procedure) -> Table:
    """Physics cross-checks: they test the measurement, not the item, and are no part of
    the statement of conformity."""
    rows = []
    for c in checks:
        row = CheckRow.of(c)
        vu, expected = row.texts(signed=False)
        rows.append((text_of(c.axis), proc.quantity(c.quantity),
                     vu, expected, "consistent" if c.verdict == "pass"
                     else "NOT CONSISTENT"))
    return Table(("Axis", "Quantity", "Measured ± U", "Expected", "Result"), tuple(rows),
                 widths=(0.8, 2.2, 2.0, 2.0, 1.3), align="llrrc",
                 caption="Consistency checks (not part of the statement of conformity)",
                 notes=("A measured value against the value physics expects (the horizontal "
                        "Earth rate 15.041 °/h · cos(latitude)): consistent when they differ by "
                        "no more than U. An inconsistency puts the measurement in doubt (e.g. "
                        "k_as, levelling); it says nothing about the item's specification.",))


def _tolerance_table(tol: Sequence[Tolerance], proc: Procedure) -> Table:
    """The procedure's tolerances: rate bands (a band applies below its `below_dps`, in
    order) or one value per quantity with its unit in the key (`<quantity>_dph: 0.5`)."""
    rows = []
    for t in tol:
        quantity = t.quantity
        words = quantity.split("_")
        if (value := t.value) is not None and words[-1] in ABSOLUTE_UNITS:
            name = " ".join(words[:-1])
            rows.append((proc.quantity("_".join(words[:-1]), name), "every measurement",
                         f"{_trim(value)} {ABSOLUTE_UNITS[words[-1]]}"))
            continue
        lo = 0.0
        for band in t.bands:
            below, rel = band.below_dps, band.rel
            if below is not None:
                where = (f"{lo:g} ≤ |ω_set| < {below:g} °/s" if lo else
                         f"|ω_set| < {below:g} °/s")
                lo = below
            else:
                where = f"|ω_set| ≥ {lo:g} °/s" if lo else "every rate"
            if rel is None:
                continue
            unit = rel_unit(rel)
            text = f"{_trim(rel * unit.scale)} {unit.name}"
            if unit is not PERCENT:
                text += f" ({_trim(rel * 100)} %)"
            rows.append((proc.quantity(quantity), where, text))
    return Table(("Quantity", "Applies to", "Tolerance T"), tuple(rows),
                 widths=(2.5, 2.5, 2.0), align="llr",
                 caption="Tolerances stated in the procedure file")


def _records(src: Sources) -> tuple[Block, ...]:
    files = list(src.frame.raw_files)
    hashed_here = False
    if not files and src.run_path is not None and layout.raw_root(src.run_path).is_dir():
        hashed_here = True
        for p in sorted(layout.raw_root(src.run_path).rglob("*")):
            if p.is_file():
                files.append(HashedFile(p.relative_to(src.run_path).as_posix(),
                                        sha256_file(p), p.stat().st_size))
    inputs = []
    if src.run_path is not None:
        for name in (layout.PROCEDURE, layout.STAND, layout.META, layout.EVENTS):
            p = src.run_path / name
            if p.is_file():   # read once: digest and byte count of the same bytes
                data = p.read_bytes()
                inputs.append(HashedFile(name, hashlib.sha256(data).hexdigest(), len(data)))
    blocks: list[Block] = [Para(
        "SHA-256 digests of the raw data as received from the instruments; anyone holding the "
        "run directory can check that the results above were computed from these bytes "
        "(`bench analyze RUN_DIR` recomputes them).")]
    if files:
        blocks.append(_hash_table(files, "Raw data files" + (
            " (hashed when this certificate was issued)" if hashed_here else "")))
    else:
        blocks.append(Para("No raw data files were recorded.", "note"))
    if inputs:
        log = next((f.size_bytes for f in inputs if f.path == layout.EVENTS), None)
        # the event log is append-only and grows after this certificate is written (the
        # run's end, the certificate's own events): its digest is of the bytes counted here
        blocks.append(_hash_table(inputs, "Run records (inputs as used and the event log)",
                                  notes=(f"events.jsonl is append-only: its digest is of its "
                                         f"first {log:.0f} bytes, the log as it stood "
                                         "when this certificate was written; events "
                                         "appended later follow them (`head -c "
                                         f"{log:.0f} events.jsonl | sha256sum`).",)
                                  if log is not None else ()))
    return tuple(blocks)


def _hash_table(files: Sequence[HashedFile], caption: str,
                notes: tuple[str, ...] = ()) -> Table:
    def size(f: HashedFile) -> str:
        return "—" if f.size_bytes is None else f"{int(f.size_bytes):,}".replace(",", " ")
    rows = tuple((text_of(f.path), size(f), text_of(f.sha256)) for f in files)
    return Table(("File", "Bytes", "SHA-256"), rows, widths=(2.6, 1.0, 5.0), align="lrl",
                 caption=caption, mono=True, notes=notes)


def restated(doc: Document, issue: Issue) -> Document:
    """`doc` with its Revision field restated for `issue` (what changed is known only once
    the new revision's statements can be compared with the replaced one's; the rest of the
    document is the same, so it is not built twice)."""
    def fields(b: Block) -> Block:
        if not isinstance(b, Fields):
            return b
        return Fields(tuple((k, _revision_text(issue) if k == "Revision" else v)
                            for k, v in b.rows))
    return dataclasses.replace(doc, sections=tuple(
        dataclasses.replace(sec, blocks=tuple(fields(b) for b in sec.blocks))
        if sec.title == "Identification" else sec for sec in doc.sections))


def _revision_text(issue: Issue) -> str:
    """Which revision, what it replaces, and (ISO/IEC 17025 7.8.8) why and what changed."""
    if issue.draft:
        text = (f"{issue.revision} (DRAFT" + (f" of a re-issue; certificate {issue.replaces} "
                                             "stands until it is issued)" if issue.replaces
                                             else ")"))
        return text
    if not issue.replaces:
        return f"{issue.revision} (first issue)"
    text = f"{issue.revision}; replaces certificate {issue.replaces}, which is withdrawn"
    if issue.reason:
        text += f". Reason: {issue.reason}"
    if issue.changes:
        text += ". What changed: " + "; ".join(issue.changes)
    return text


def _signatures(src: Sources, issue: Issue) -> tuple[Block, ...]:
    """Who performed the calibration (the account the register authenticated at the run's
    start, else "not recorded") and who authorised the issue (the account it authenticated
    at issue: printed name, date and time, meaning). Names in a file sign nothing."""
    name, how = performer(src.start)
    pairs: list[tuple[str, str]] = [(PERFORMED_BY, name)]
    performed = Para(performer_line(src.start), "note")
    if issue.draft:
        pairs.append(("Reviewed and authorised by", ""))
        how_issued = ("A signatory of the lab register issues it (`bench authorise RUN_DIR "
                      "--signatory ACCOUNT`, or the station view), authenticated by name and "
                      "password." if src.meta.get("equipment_register") else
                      # issue 54: no register, no issue
                      "It can never be issued: no lab register was named when the run "
                      "started, so no register holds the run's record from its start; an "
                      "issue is made only from that record. Measure under the lab's "
                      "register (register: URL in the lab file, docs/register.md).")
        return (Para("DRAFT, NOT AUTHORISED: this draft has not been authorised for issue "
                     f"and is not a certificate. {how_issued}", "strong"), performed,
                Signatures(tuple(pairs)))
    who = ", ".join(x for x in (issue.signatory, issue.function) if x)
    meaning = issue.meaning or "authorised for issue"
    pairs.append((f"{issue.function or 'Authorised signatory'}; {meaning} "
                  f"({issue.issued_utc})", str(issue.signatory)))
    text = (f"Date of issue: {issue.issue_date}, the date on which this certificate was "
            f"authorised for issue by {who} ({issue.issued_utc}).")
    if issue.register:
        text += (f" Electronic signature: {issue.signatory}, {issue.issued_utc}, meaning "
                 f"'{meaning}', authenticated by name and password by the lab register "
                 f"{issue.register}.")
    if issue.receipt:
        text += f" {issue.receipt}."
    if issue.replaces:
        text += (f" Revision {issue.revision}: it replaces certificate {issue.replaces}, "
                 "which is withdrawn.")
        if issue.reason:
            text += f" Reason for the re-issue: {issue.reason}."
    return (Para(text), performed, Signatures(tuple(pairs)))
