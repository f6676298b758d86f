"""The summary `bench run` and `bench analyze` print at the end: the certificate's own cells.

The summary is cut from the certificate's document model (the tables the certificate
prints), never formatted a second time, so every number on the console is the
certificate's text for the same quantity: U to two significant digits, the value to
match, unresolved figures as "< limit", the unit in the column header.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from bench.app.console.report import STATEMENT_FIELD, Summary, SummaryTable
from bench.report.certificate.model import Document, Fields, Table

# (caption after "Axis <name>: ", header prefix in the certificate, header on the console)
LADDER_COLUMNS = (
    ("per-turn rate error", "Set rate", None),
    ("per-turn rate error", "Turns", None),
    ("per-turn rate error", "Rate error", None),
    ("per-turn rate error", "Instability", None),
    ("intra-turn instability", "Raw ± U", "Intra-turn raw ± U"),
    ("intra-turn instability", "Floor-corrected", None),
    ("per-turn rate error", "Verdict", None),
)
PAIR_COLUMNS = (
    ("FOG cross-calibration", "Pair", None),
    ("FOG cross-calibration", "k ± U", None),
    ("FOG cross-calibration", "ω0 ± U, °/s", None),
)
DRIFT_CAPTION = "Own and apparent drift per axis"
DRIFT_HEADERS = ("Axis", "Own drift", "Apparent drift")
AZIMUTH_FIELD = "Platform azimuth"


def _tables(doc: Document) -> list[Table]:
    return [b for s in doc.sections for b in s.blocks if isinstance(b, Table)]


def _fields(doc: Document) -> dict[str, str]:
    return {k: v for s in doc.sections for b in s.blocks if isinstance(b, Fields)
            for k, v in b.rows}


def _column(table: Table, prefix: str) -> int | None:
    return next((i for i, h in enumerate(table.header) if h.startswith(prefix)), None)


def _axis_tables(doc: Document) -> dict[str, dict[str, Table]]:
    """Per axis, its tables keyed by caption (the text after 'Axis <name>: ')."""
    out: dict[str, dict[str, Table]] = {}
    for t in _tables(doc):
        m = re.match(r"Axis (\S+): (.*)", t.caption)
        if m:
            out.setdefault(m.group(1), {})[m.group(2)] = t
    return out


def _find(tables: dict[str, Table], caption: str) -> Table | None:
    return next((t for c, t in tables.items() if c.startswith(caption)), None)


def _joined(title: str, tables: dict[str, Table],
            columns: Sequence[tuple[str, str, str | None]]) -> SummaryTable | None:
    """Columns of several tables of one axis, rows joined on the first column (the rate)."""
    picked: list[tuple[Table, int, str]] = []
    for caption, prefix, shown in columns:
        t = _find(tables, caption)
        i = _column(t, prefix) if t is not None else None
        if t is not None and i is not None:
            name = t.header[i]
            picked.append((t, i, shown + name[len(prefix):] if shown else name))
    if not picked:
        return None
    base = picked[0][0]
    keyed = {id(t): {row[0]: row for row in t.rows} for t, _, _ in picked}
    rows = []
    for key in (row[0] for row in base.rows):
        cells = []
        for t, i, _ in picked:
            row = keyed[id(t)].get(key)
            cells.append(row[i] if row is not None else "—")
        rows.append(tuple(cells))
    align = "".join((t.align[i] if i < len(t.align) else "r") for t, i, _ in picked)
    return SummaryTable(title, tuple(name for _, _, name in picked), tuple(rows), align)


def summarize(doc: Document) -> Summary:
    """The figures the console shows, as the certificate prints them."""
    tables: list[SummaryTable] = []
    for axis, by_caption in _axis_tables(doc).items():
        for title, columns in ((f"Axis {axis}", LADDER_COLUMNS),
                               (f"Axis {axis}, FOG cross-calibration per ± pair", PAIR_COLUMNS)):
            t = _joined(title, by_caption, columns)
            if t is not None and t.rows:
                tables.append(t)
    drift = next((t for t in _tables(doc) if t.caption.startswith(DRIFT_CAPTION)), None)
    if drift is not None:
        idx = [i for p in DRIFT_HEADERS for i in (_column(drift, p),) if i is not None]
        tables.append(SummaryTable("Drift", tuple(drift.header[i] for i in idx),
                                   tuple(tuple(r[i] for i in idx) for r in drift.rows),
                                   "".join(drift.align[i] if i < len(drift.align) else "r"
                                           for i in idx)))
    fields = _fields(doc)
    picked = tuple((k, v) for k, v in fields.items() if k.startswith(AZIMUTH_FIELD))
    verdict = str(doc.verdict or "incomplete").upper()
    return Summary(tuple(tables), picked, fields.get(STATEMENT_FIELD, ""), verdict)
