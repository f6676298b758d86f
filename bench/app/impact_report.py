"""The impact report of `bench impact SERIAL --report DIR` (issue 58) as PDF and HTML beside
its JSON, and per customer a draft notification (text and HTML).

Why the certificate's stack: the report is laid out as a `Document`
(bench/report/certificate/model.py) and rendered by the certificate's own PDF (fpdf2) and
HTML (Jinja2) renderers, so the two formats cannot disagree about a number, and every
number comes from the document `bench impact --json` writes (`ImpactReport`,
bench/app/impact_codec.py, typed): the report is that document laid out, nothing
recomputed.

Layout: a summary table first (per run: certificate number and revisions, customer, the
figure that moved most against its U, the shift in its unit and over U, marked `*` over
U/3, the conformity outcomes that change), the finding, then a page per affected
certificate with every figure's shift and each changed conformity statement.

The notifications are drafts: the lab reviews and sends them (ISO/IEC 17025 7.10.1 d,
the customer informed where the nonconforming work affected the results). One per
customer the issued certificates name, naming that customer's certificates and what
changed in each.
"""

from __future__ import annotations

import hashlib
import html
import re
from collections.abc import Sequence
from pathlib import Path

from bench.app.impact_codec import CheckChange, FigureShift, ImpactReport, RunImpact
from bench.report.certificate.model import Document, Fields, Para, Section, Table

#: a shift over this fraction of its figure's U is marked (as in bench/app/impact.py)
MARK = "*"
NO_CUSTOMER = "customer not stated"


def _g(x: float | None, digits: int = 4) -> str:
    return "" if x is None else f"{x:.{digits}g}"


def _signed(x: float, digits: int = 3) -> str:
    return f"{x:+.{digits}g}"


def customer_of(run: RunImpact) -> str:
    return run.customer.customer if run.customer and run.customer.customer else NO_CUSTOMER


def certificate_of(run: RunImpact) -> str:
    """The certificate number and its revisions as the register holds them."""
    return ", ".join(run.revisions) if run.revisions else run.number or "not issued"


def change_text(c: CheckChange) -> str:
    at = c.set_rate_dps
    where = c.axis + ("" if at is None else f" {at:g} deg/s")
    return f"{where} {c.quantity}: {c.issued} -> {c.corrected}"


def figure_name(f: FigureShift) -> str:
    return f"{f.where} {f.name}"


def _shift_over_u(f: FigureShift) -> str:
    return _signed(f.shift_over_u) + (f" {MARK}" if f.marked else "")


def summary_rows(doc: ImpactReport) -> list[tuple[str, ...]]:
    """Per run: run, certificate (number, revisions), customer, figure, shift in its unit,
    shift / U (marked), conformity changes; a run not re-analysed says why instead."""
    rows: list[tuple[str, ...]] = []
    for run in doc.runs:
        big = run.largest()
        changes = run.checks_changed
        if not run.reanalysed or big is None:
            figure, shift, over = run.status, "", ""
        else:
            figure = figure_name(big)
            shift = f"{_signed(big.shift)} {big.unit}"
            over = _shift_over_u(big)
        changed = ("; ".join(change_text(c) for c in changes) if changes else
                   "none" if run.reanalysed else "not assessed")
        rows.append((run.uid, certificate_of(run), customer_of(run), figure, shift, over,
                     changed))
    return rows


def _finding_rows(doc: ImpactReport) -> tuple[tuple[str, str], ...]:
    f = doc.finding
    err = _g(f.error, 6) + ("" if f.error_u is None else f" (U {_g(f.error_u, 3)})")
    since = (f"{f.since_certificate} ({f.since})" if f.since
             else "the inventory's first record")
    return (("Item", f"{f.model}, serial {f.serial}"),
            ("Calibration with the finding", f"{f.certificate} ({f.issuer}, "
                                             f"{f.calibrated_on}), found "
                                             f"{f.found or 'not stated'}"),
            ("As-found error", err),
            ("Runs assessed since", since),
            ("Register", doc.register))


def title_of(doc: ImpactReport) -> str:
    return f"Impact of {doc.finding.model} serial {doc.finding.serial} found out of tolerance"


SUMMARY_HEADER = ("Run", "Certificate (revisions)", "Customer", "Figure (largest shift/U)",
                  "Shift", "Shift / U", "Conformity changes")


def build(doc: ImpactReport, laboratory: str, date: str) -> Document:
    """The report as a Document: summary first, the finding, a page per certificate."""
    mark = doc.mark_fraction_of_U or 1.0 / 3.0
    runs = doc.runs
    done = [r for r in runs if r.reanalysed]
    sections = [
        Section("1", "Summary", (
            Para(f"{len(runs)} run(s) used the item in the period; {len(done)} analysed "
                 "again from their raw captures with the as-found error applied as a "
                 "correction; "
                 f"{sum(1 for r in runs if r.status.startswith('raw data'))} "
                 "whose raw data was not found (listed, not re-analysed)."),
            Table(SUMMARY_HEADER, tuple(summary_rows(doc)),
                  widths=(3.8, 1.5, 1.1, 2.0, 1.0, 0.9, 1.2), align="lllllrl",
                  caption="Each run's figure that moved most against its U (corrected "
                          "minus issued)",
                  notes=(f"{MARK} a shift over {mark:.2g} of the figure's expanded U "
                         "(about 95 %).",)))),
        Section("2", "The finding", (Fields(_finding_rows(doc)),)),
    ]
    for i, run in enumerate(done, start=3):
        figs = run.figures
        changes = run.checks_changed
        blocks: list[Fields | Table | Para] = [
            Fields((("Run", run.uid),
                    ("Certificate (revisions)", certificate_of(run)),
                    ("Customer", customer_of(run)),
                    ("The item's place on the stand", run.where),
                    ("Registered", run.registered_utc))),
            Table(("Where", "Figure", "Unit", "Issued", "Corrected", "Shift", "U",
                   "Shift / U"),
                  tuple((f.where, f.name, f.unit, _g(f.issued, 7), _g(f.corrected, 7),
                         _signed(f.shift), _g(f.u_issued, 3),
                         _shift_over_u(f)) for f in figs),
                  widths=(2.0, 2.2, 0.7, 1.3, 1.3, 1.0, 0.9, 0.9), align="llllrrrr",
                  caption="Each figure that states a U, issued and analysed again with the "
                          "correction")]
        blocks.append(Table(("Check", "Issued", "Corrected"),
                            tuple((change_text(c).split(":")[0], c.issued, c.corrected)
                                  for c in changes),
                            caption="Conformity statements whose outcome changes")
                      if changes else Para("Conformity: no statement's outcome changes."))
        sections.append(Section(str(i), f"Certificate {certificate_of(run)}", tuple(blocks),
                                new_page=True))
    return Document(
        cert_id=f"impact {_finding_serial(doc)}", title="Impact report",
        subtitle=title_of(doc), laboratory=laboratory, issue_date=date, verdict="",
        sections=tuple(sections),
        footer="Impact of nonconforming work (ISO/IEC 17025 7.10, 6.4.13): the runs the "
               "lab register holds that used the item, analysed again with its as-found "
               "error (ratebench bench impact). Numbers as in the report's JSON.",
        end_text="End of impact report",
        meta={"header_label": f"Impact report, item {_finding_serial(doc)}",
              "run_title": "", "scope": "", "replaces": "", "revision": ""})


def _finding_serial(doc: ImpactReport) -> str:
    return doc.finding.serial


# -- the notifications ---------------------------------------------------------------------

def _slug(name: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", name.casefold()).strip("-") or "customer"


def notification_lines(doc: ImpactReport, customer: str, runs: Sequence[RunImpact],
                       laboratory: str) -> list[str]:
    """One customer's draft: the item and finding, then each certificate and what changed."""
    f = doc.finding
    contact = runs[0].customer if runs else None
    address = contact.customer_address if contact else None
    attention = contact.customer_contact if contact else None
    lines = ["DRAFT - to be reviewed and sent by the laboratory, not sent",
             f"From: {laboratory}",
             f"To: {customer}" + (f", {address}" if address else ""),
             *([f"Attention: {attention}"] if attention else []),
             f"Subject: calibration certificates affected by {f.model} serial "
             f"{f.serial} found out of tolerance",
             "",
             f"The {f.model} serial {f.serial} used in your calibrations was "
             f"found out of tolerance at its calibration {f.certificate} "
             f"({f.calibrated_on}): as-found error {_g(f.error, 6)}"
             + ("" if f.error_u is None else f" (U {_g(f.error_u, 3)})")
             + ". We analysed the raw data of each certificate below again with this error "
               "corrected. Shifts are corrected minus issued; U is the issued expanded "
               "uncertainty (about 95 %); * marks a shift over a third of U.",
             ""]
    for run in runs:
        lines.append(f"Certificate {certificate_of(run)} (run {run.uid}): {run.status}")
        for fig in run.figures:
            if fig.marked:
                lines.append(f"  {figure_name(fig)}: issued {_g(fig.issued, 7)}, "
                             f"corrected {_g(fig.corrected, 7)} {fig.unit}, "
                             f"shift {_signed(fig.shift)} ({_shift_over_u(fig)} U)")
        if run.reanalysed:
            if not any(fig.marked for fig in run.figures):
                big = run.largest()
                lines.append("  no figure moved by more than a third of its U"
                             + (f" (largest: {figure_name(big)}, "
                                f"{_shift_over_u(big)} U)" if big else ""))
            changes = run.checks_changed
            lines += [f"  conformity statement changes: {change_text(c)}" for c in changes] \
                or ["  conformity statements: no outcome changes"]
        lines.append("")
    lines.append("We will issue corrected certificates where a statement changes and "
                 "answer any question about the figures above.")
    return lines


def _html_page(title: str, lines: Sequence[str]) -> str:
    body = "\n".join(f"<p>{html.escape(line)}</p>" if not line.startswith("  ")
                     else f"<p style=\"margin-left:2em\">{html.escape(line.strip())}</p>"
                     for line in lines if line)
    return (f"<!DOCTYPE html>\n<html lang=\"en\">\n<head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title></head>\n<body>\n{body}\n</body>\n</html>\n")


def notifications(doc: ImpactReport, laboratory: str
                  ) -> dict[str, tuple[list[RunImpact], list[str]]]:
    """Per customer of an issued certificate: its runs and its draft's lines."""
    by: dict[str, list[RunImpact]] = {}
    for run in doc.runs:
        if run.number:       # drafts were never sent: nobody to notify
            by.setdefault(customer_of(run), []).append(run)
    return {c: (runs, notification_lines(doc, c, runs, laboratory)) for c, runs in by.items()}


def write_report(folder: Path, doc: ImpactReport, json_text: str, laboratory: str,
                 date: str) -> list[Path]:
    """The report (JSON, PDF, HTML) and the per-customer drafts in `folder`; the paths."""
    from bench.app.certificate.html import render_html
    from bench.app.certificate.pdf import render_pdf

    folder.mkdir(parents=True, exist_ok=True)
    stem = f"impact-{_slug(_finding_serial(doc))}"
    report = build(doc, laboratory, date)
    out = [folder / f"{stem}.json", folder / f"{stem}.pdf", folder / f"{stem}.html"]
    out[0].write_text(json_text, encoding="utf-8")
    out[1].write_bytes(render_pdf(report))
    out[2].write_text(render_html(report), encoding="utf-8")
    for customer, (_runs_of, lines) in notifications(doc, laboratory).items():
        name = folder / f"notification-{_slug(customer)}"
        txt, page = name.with_suffix(".txt"), name.with_suffix(".html")
        txt.write_text("\n".join(lines) + "\n", encoding="utf-8")
        page.write_text(_html_page(f"Notification to {customer}", lines), encoding="utf-8")
        out += [txt, page]
    return out


def digests(paths: Sequence[Path]) -> dict[str, str]:
    """Each file's SHA-256 by name (the audit entry ties the report to the assessment)."""
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in paths}
