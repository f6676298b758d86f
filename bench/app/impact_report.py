"""The impact report of `bench impact SERIAL --report DIR` (issue 58) as PDF and HTML beside
its JSON, and per customer a draft notification (text and HTML).

Why the certificate's stack: the report is laid out as a `Document`
(bench/report/certificate/model.py) and rendered by the certificate's own PDF (fpdf2) and
HTML (Jinja2) renderers, so the two formats cannot disagree about a number, and every
number comes from the JSON document `bench impact --json` writes (`report_json`): the
report is that document laid out, nothing recomputed.

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
from collections.abc import Mapping, Sequence
from pathlib import Path

from bench.report.certificate.model import Document, Fields, Para, Section, Table

#: a shift over this fraction of its figure's U is marked (as in bench/app/impact.py)
MARK = "*"
NO_CUSTOMER = "customer not stated"


def _num(x: object) -> float | None:
    return float(x) if isinstance(x, int | float) and not isinstance(x, bool) else None


def _g(x: object, digits: int = 4) -> str:
    v = _num(x)
    return "" if v is None else f"{v:.{digits}g}"


def _signed(x: object, digits: int = 3) -> str:
    v = _num(x)
    return "" if v is None else f"{v:+.{digits}g}"


def customer_of(run: Mapping[str, object]) -> str:
    c = run.get("customer")
    name = c.get("customer") if isinstance(c, Mapping) else None
    return str(name) if name else NO_CUSTOMER


def certificate_of(run: Mapping[str, object]) -> str:
    """The certificate number and its revisions as the register holds them."""
    revs = run.get("revisions")
    if isinstance(revs, list) and revs:
        return ", ".join(str(r) for r in revs)
    return str(run.get("number") or "not issued")


def _figures(run: Mapping[str, object]) -> list[Mapping[str, object]]:
    got = run.get("figures")
    return [f for f in got if isinstance(f, Mapping)] if isinstance(got, list) else []


def _changes(run: Mapping[str, object]) -> list[Mapping[str, object]]:
    got = run.get("checks_changed")
    return [c for c in got if isinstance(c, Mapping)] if isinstance(got, list) else []


def largest(run: Mapping[str, object]) -> Mapping[str, object] | None:
    """The figure whose shift is the largest fraction of its U."""
    return max(_figures(run), key=lambda f: abs(_num(f.get("shift_over_u")) or 0.0),
               default=None)


def change_text(c: Mapping[str, object]) -> str:
    at = _num(c.get("set_rate_dps"))
    where = f"{c.get('axis')}" + ("" if at is None else f" {at:g} deg/s")
    return f"{where} {c.get('quantity')}: {c.get('issued')} -> {c.get('corrected')}"


def figure_name(f: Mapping[str, object]) -> str:
    return f"{f.get('where')} {f.get('name')}"


def _shift_over_u(f: Mapping[str, object]) -> str:
    return _signed(f.get("shift_over_u")) + (f" {MARK}" if f.get("marked") else "")


def summary_rows(doc: Mapping[str, object]) -> list[tuple[str, ...]]:
    """Per run: run, certificate (number, revisions), customer, figure, shift in its unit,
    shift / U (marked), conformity changes; a run not re-analysed says why instead."""
    rows: list[tuple[str, ...]] = []
    for run in _runs(doc):
        big = largest(run)
        changes = _changes(run)
        if run.get("status") != "re-analysed" or big is None:
            figure, shift, over = str(run.get("status")), "", ""
        else:
            figure = figure_name(big)
            shift = f"{_signed(big.get('shift'))} {big.get('unit')}"
            over = _shift_over_u(big)
        changed = ("; ".join(change_text(c) for c in changes) if changes else
                   "none" if run.get("status") == "re-analysed" else "not assessed")
        rows.append((str(run.get("uid")), certificate_of(run), customer_of(run), figure,
                     shift, over, changed))
    return rows


def _runs(doc: Mapping[str, object]) -> list[Mapping[str, object]]:
    got = doc.get("runs")
    return [r for r in got if isinstance(r, Mapping)] if isinstance(got, list) else []


def _finding_rows(doc: Mapping[str, object]) -> tuple[tuple[str, str], ...]:
    f = doc.get("finding")
    f = f if isinstance(f, Mapping) else {}
    err = _g(f.get("error"), 6) + ("" if f.get("error_u") is None
                                   else f" (U {_g(f.get('error_u'), 3)})")
    since = (f"{f.get('since_certificate')} ({f.get('since')})" if f.get("since")
             else "the inventory's first record")
    return (("Item", f"{f.get('model')}, serial {f.get('serial')}"),
            ("Calibration with the finding", f"{f.get('certificate')} ({f.get('issuer')}, "
                                             f"{f.get('calibrated_on')}), found "
                                             f"{f.get('found') or 'not stated'}"),
            ("As-found error", err),
            ("Runs assessed since", str(since)),
            ("Register", str(doc.get("register"))))


def title_of(doc: Mapping[str, object]) -> str:
    f = doc.get("finding")
    f = f if isinstance(f, Mapping) else {}
    return f"Impact of {f.get('model')} serial {f.get('serial')} found out of tolerance"


SUMMARY_HEADER = ("Run", "Certificate (revisions)", "Customer", "Figure (largest shift/U)",
                  "Shift", "Shift / U", "Conformity changes")


def build(doc: Mapping[str, object], laboratory: str, date: str) -> Document:
    """The report as a Document: summary first, the finding, a page per certificate."""
    mark = _num(doc.get("mark_fraction_of_U")) or 1.0 / 3.0
    runs = _runs(doc)
    done = [r for r in runs if r.get("status") == "re-analysed"]
    sections = [
        Section("1", "Summary", (
            Para(f"{len(runs)} run(s) used the item in the period; {len(done)} analysed "
                 "again from their raw captures with the as-found error applied as a "
                 "correction; "
                 f"{sum(1 for r in runs if str(r.get('status')).startswith('raw data'))} "
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
        figs = _figures(run)
        changes = _changes(run)
        blocks: list[Fields | Table | Para] = [
            Fields((("Run", str(run.get("uid"))),
                    ("Certificate (revisions)", certificate_of(run)),
                    ("Customer", customer_of(run)),
                    ("The item's place on the stand", str(run.get("where"))),
                    ("Registered", str(run.get("registered_utc"))))),
            Table(("Where", "Figure", "Unit", "Issued", "Corrected", "Shift", "U",
                   "Shift / U"),
                  tuple((str(f.get("where")), str(f.get("name")), str(f.get("unit")),
                         _g(f.get("issued"), 7), _g(f.get("corrected"), 7),
                         _signed(f.get("shift")), _g(f.get("u_issued"), 3),
                         _shift_over_u(f)) for f in figs),
                  widths=(2.0, 2.2, 0.7, 1.3, 1.3, 1.0, 0.9, 0.9), align="llllrrrr",
                  caption="Each figure that states a U, issued and analysed again with the "
                          "correction")]
        blocks.append(Table(("Check", "Issued", "Corrected"),
                            tuple((change_text(c).split(":")[0], str(c.get("issued")),
                                   str(c.get("corrected"))) for c in changes),
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


def _finding_serial(doc: Mapping[str, object]) -> str:
    f = doc.get("finding")
    return str(f.get("serial")) if isinstance(f, Mapping) else "?"


# -- the notifications ---------------------------------------------------------------------

def _slug(name: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", name.casefold()).strip("-") or "customer"


def notification_lines(doc: Mapping[str, object], customer: str,
                       runs: Sequence[Mapping[str, object]], laboratory: str) -> list[str]:
    """One customer's draft: the item and finding, then each certificate and what changed."""
    f = doc.get("finding")
    f = f if isinstance(f, Mapping) else {}
    first = runs[0].get("customer") if runs else None
    contact = first if isinstance(first, Mapping) else {}
    lines = ["DRAFT - to be reviewed and sent by the laboratory, not sent",
             f"From: {laboratory}",
             f"To: {customer}" + (f", {contact.get('customer_address')}"
                                  if contact.get("customer_address") else ""),
             *([f"Attention: {contact.get('customer_contact')}"]
               if contact.get("customer_contact") else []),
             f"Subject: calibration certificates affected by {f.get('model')} serial "
             f"{f.get('serial')} found out of tolerance",
             "",
             f"The {f.get('model')} serial {f.get('serial')} used in your calibrations was "
             f"found out of tolerance at its calibration {f.get('certificate')} "
             f"({f.get('calibrated_on')}): as-found error {_g(f.get('error'), 6)}"
             + ("" if f.get("error_u") is None else f" (U {_g(f.get('error_u'), 3)})")
             + ". We analysed the raw data of each certificate below again with this error "
               "corrected. Shifts are corrected minus issued; U is the issued expanded "
               "uncertainty (about 95 %); * marks a shift over a third of U.",
             ""]
    for run in runs:
        lines.append(f"Certificate {certificate_of(run)} (run {run.get('uid')}): "
                     f"{run.get('status')}")
        for fig in _figures(run):
            if fig.get("marked"):
                lines.append(f"  {figure_name(fig)}: issued {_g(fig.get('issued'), 7)}, "
                             f"corrected {_g(fig.get('corrected'), 7)} {fig.get('unit')}, "
                             f"shift {_signed(fig.get('shift'))} ({_shift_over_u(fig)} U)")
        if run.get("status") == "re-analysed":
            if not any(fig.get("marked") for fig in _figures(run)):
                big = largest(run)
                lines.append("  no figure moved by more than a third of its U"
                             + (f" (largest: {figure_name(big)}, "
                                f"{_shift_over_u(big)} U)" if big else ""))
            changes = _changes(run)
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


def notifications(doc: Mapping[str, object], laboratory: str
                  ) -> dict[str, tuple[list[Mapping[str, object]], list[str]]]:
    """Per customer of an issued certificate: its runs and its draft's lines."""
    by: dict[str, list[Mapping[str, object]]] = {}
    for run in _runs(doc):
        if run.get("number"):       # drafts were never sent: nobody to notify
            by.setdefault(customer_of(run), []).append(run)
    return {c: (runs, notification_lines(doc, c, runs, laboratory)) for c, runs in by.items()}


def write_report(folder: Path, doc: Mapping[str, object], json_text: str, laboratory: str,
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
