"""The summary `bench run` and `bench analyze` print at the end: the certificate's own cells.

The run's procedure kind says which cells of its certificate the console shows
(`bench.kind.SummarisesRun`), so every number on the console is the certificate's
text for the same quantity: U to two significant digits, the value to match,
unresolved figures as "< limit", the unit in the column header. A kind that says
nothing gets its declared figures (`bench.kind.RecordsPart`), each printed by
the certificate's rounding rule (docs/certificate.md) with its check's verdict.
"""

from __future__ import annotations

from collections.abc import Mapping

from bench.app.console.report import STATEMENT_FIELD, Summary, SummaryTable
from bench.app.records.extract import figures_of, kind_name
from bench.kind import SummarisesRun, installed_records
from bench.report.certificate.model import Document, Table
from bench.report.certificate.parts import verdict_label
from bench.report.certificate.rounding import format_value_u
from bench.report.figures import SummaryCut, fields_of, spec_for
from bench.report.result_frame import JsonValue, ResultFrame


def _declared(frame: ResultFrame, name: str) -> SummaryCut:
    """The kind's declared figures as one table: where, quantity, value ± U, verdict."""
    kind = installed_records(name)
    if kind is None:
        return SummaryCut()
    rows = []
    for f in figures_of(frame, name):
        spec = spec_for(f.quantity, kind.figures)
        scale, unit = (spec.scale, spec.shown) if spec is not None else (1.0, f.unit)
        shown = format_value_u(f.value, f.u, scale, signed=True)
        text = (f"< {shown.value}" if f.is_limit else
                shown.value if shown.u is None else f"{shown.value} ± {shown.u}")
        rate = "" if f.set_rate_dps is None else f"{f.set_rate_dps:+g} °/s"
        words = spec.name if spec is not None else f.quantity
        rows.append((" ".join(x for x in (f.axis, rate) if x) or "—",
                     f"{words}, {unit}" if unit not in ("", "1") else words, text,
                     verdict_label(f.verdict) if f.verdict else "—"))
    if not rows:
        return SummaryCut()
    return SummaryCut((Table(("Where", "Quantity", "Value ± U", "Verdict"), tuple(rows),
                             align="llrc", caption="Results"),))


def summarize(doc: Document, result: ResultFrame | Mapping[str, JsonValue] | None = None
              ) -> Summary:
    """The figures the console shows, as the certificate prints them, of the result's
    frame (as the analysis gave it, or result.json's)."""
    frame = result if isinstance(result, ResultFrame) else ResultFrame.of(dict(result or {}))
    name = kind_name(frame)
    kind = installed_records(name)
    cut = (kind.summary_cut(doc) if isinstance(kind, SummarisesRun)
           else _declared(frame, name))
    tables = tuple(SummaryTable(t.caption, t.header, t.rows, t.align or "r" * len(t.header))
                   for t in cut.tables)
    fields = fields_of(doc)
    verdict = str(doc.verdict or "incomplete").upper()
    return Summary(tables, cut.fields, fields.get(STATEMENT_FIELD, ""), verdict)
