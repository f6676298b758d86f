"""The figures a procedure kind reports, declared before any run, and their rows.

A run's results are described before they are measured (Bluesky's event descriptors,
QCoDeS's parameters): each kind declares its figures (`FigureSpec`: the records' key
with the unit in its name, words, unit, where result.json holds it and its U, the check
that judges it, how `bench history` prints it and how the trend plot draws it), and
turns a result.json into rows of them (`FigureValue`). Everything that shows a kind's
figures outside its certificate (the records database, `bench history`, the trend plot,
the console summary, the station view) reads these and nothing else, so a new kind's
figures reach all of them from its own package.

A kind that only declares (`DeclaredFigures.figures`) gets its rows from the paths it
declared (`values_at`); one whose figures need more (a limit in place of an unresolved
value, a family of harmonics) writes `figure_values` itself. The console summary cuts
the kind's own certificate cells (`SummaryCut`, docs/certificate.md) when the kind says
which; otherwise it lists the declared figures.

Nothing here names a procedure kind.
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass

import msgspec

from bench.analysis.finite import finite_number
from bench.report.certificate.model import Document, Fields, Table
from bench.report.result_frame import Node, ResultFrame, at, entries

#: the trend plot's tolerance bands: +-T around zero, 0..T (a spread), or none
BANDS = ("sym", "upper", "")


@dataclass(frozen=True)
class Trend:
    """How the trend plot draws a figure across runs: plotted = (value - offset) * scale,
    with U (k = 2) bars and its check's tolerance as a band."""

    band: str = ""            # one of BANDS
    offset: float = 0.0       # e.g. 1 for a scale factor k, drawn as k - 1
    label: str = ""           # the panel's axis label; default "<name>, <shown unit>"


@dataclass(frozen=True)
class FigureSpec:
    """One figure a kind reports (declared once; every consumer reads this).

    `path` is where result.json holds the value: keys joined by dots, `<axis>` for a
    mapping whose keys are the axes (or gyros), `name[]` for a list; `u_path` is the key of
    its expanded uncertainty (k = 2) beside the value; `rate_key` the key of the enclosing
    list entry that gives the rate. A quantity with `<...>` in it is a family (one figure
    per order, say), matched by `matches`.
    """

    quantity: str             # the records' key, unit in the name: rate_error_rel
    name: str                 # in words, for `bench history` and the summary
    unit: str                 # the stored unit: "1" (fractions, k), "deg/s", "deg/h", "s"
    description: str
    path: str                 # result.json: "axes.<axis>.rates[].rate_error_rel"
    u_path: str | None = None            # "rate_error_u_rel"; None: no U is reported
    rate_key: str | None = None          # "set_rate_dps"
    rate_is_magnitude: bool = False      # the rate is a +/- pair's magnitude
    axis: str = ""                       # the axis of a path without <axis> ("platform")
    check: str | None = None             # the checks[] quantity that judges it
    shown_unit: str = ""                 # the unit `bench history` and the trend print
    scale: float = 1.0                   # stored value x scale = shown value
    trend: Trend | None = None           # drawn by the trend plot (None: recorded only)
    listed: bool = False                 # listed by `bench history` (its CSV has all)
    compared: str | None = None          # words in the as-found/as-left comparison

    @property
    def shown(self) -> str:
        return self.shown_unit or self.unit

    @property
    def trend_label(self) -> str:
        return (self.trend.label if self.trend and self.trend.label
                else f"{self.name}, {self.shown}")

    def matches(self, quantity: str) -> bool:
        if "<" not in self.quantity:
            return quantity == self.quantity
        pattern = re.sub(r"<[^>]*>", ".+", re.escape(self.quantity).replace(r"\<", "<")
                         .replace(r"\>", ">"))
        return re.fullmatch(pattern, quantity) is not None


@dataclass(frozen=True)
class FigureValue:
    """One figure of one run, as the kind read it from result.json."""

    axis: str
    quantity: str
    set_rate_dps: float | None
    value: float
    u: float | None               # expanded, k = 2, same unit
    unit: str
    check: str | None = None      # the checks[] quantity that judges it
    upper_limit: bool = False     # not resolved: `value` is a one-sided upper limit


@dataclass(frozen=True)
class InstrumentCheck:
    """One check value of one instrument in one run, with U (k = 2) where it has one
    (measurement assurance, docs/method.md C1; the records' `CheckRecord`)."""

    serial: str
    role: str                    # fog | counter | drive | gyro | ...
    model: str | None
    axis: str
    quantity: str
    set_rate_dps: float | None   # |rate| for per-rate values, else None
    value: float
    u: float | None
    unit: str


def spec_for(quantity: str, specs: Sequence[FigureSpec]) -> FigureSpec | None:
    """The declaration of a recorded quantity among `specs` (the first that matches)."""
    return next((s for s in specs if s.matches(quantity)), None)


def _walk(node: Node, parts: Sequence[str], axis: str, rate: float | None,
          spec: FigureSpec) -> Iterator[tuple[str, float | None, float | None, float | None]]:
    """(axis, rate, value, U) for every match of `parts` (the value's key last)."""
    if not isinstance(node, Mapping | msgspec.Struct):
        return
    head, rest = parts[0], parts[1:]
    if not rest:
        yield (axis, rate, finite_number(at(node, head)),
               finite_number(at(node, spec.u_path)) if spec.u_path else None)
        return
    if head == "<axis>":
        for key, child in node.items() if isinstance(node, Mapping) else ():
            yield from _walk(child, rest, str(key), rate, spec)
        return
    if head.endswith("[]"):
        items = at(node, head[:-2])
        for item in items if isinstance(items, list | tuple) else ():
            here = rate
            if spec.rate_key and spec.rate_key in dict(entries(item)):
                here = finite_number(at(item, spec.rate_key))
            yield from _walk(item, rest, axis, here, spec)
        return
    yield from _walk(at(node, head), rest, axis, rate, spec)


def values_at(frame: ResultFrame, specs: Sequence[FigureSpec]) -> list[FigureValue]:
    """Every declared figure the run's result.json holds, read at its declared path."""
    out = []
    for spec in specs:
        if "<" in spec.quantity:
            continue          # a family: the kind reads it itself
        # the kind's own model when its analysis has just given it, else result.json's
        top = frame.body if isinstance(frame.body, msgspec.Struct) else frame.doc
        for axis, rate, value, u in _walk(top, spec.path.split("."), spec.axis, None, spec):
            if value is None:
                continue
            if spec.rate_is_magnitude and rate is not None:
                rate = abs(rate)
            out.append(FigureValue(axis, spec.quantity, rate, value, u, spec.unit, spec.check))
    return out


class DeclaredFigures:
    """A kind's figures from their declarations alone (inherit it, set `figures`)."""

    figures: tuple[FigureSpec, ...] = ()

    def figure_values(self, frame: ResultFrame) -> list[FigureValue]:
        return values_at(frame, self.figures)


# -- the console summary: cells cut from the kind's own certificate ------------------------

@dataclass(frozen=True)
class SummaryCut:
    """What the console summary shows of a certificate: tables (their caption is the
    summary's title) and single fields, each cell the certificate's own text."""

    tables: tuple[Table, ...] = ()
    fields: tuple[tuple[str, str], ...] = ()


def tables_of(doc: Document) -> list[Table]:
    return [b for s in doc.sections for b in s.blocks if isinstance(b, Table)]


def fields_of(doc: Document) -> dict[str, str]:
    return {k: v for s in doc.sections for b in s.blocks if isinstance(b, Fields)
            for k, v in b.rows}


def column(table: Table, prefix: str) -> int | None:
    """The first column whose header starts with `prefix`."""
    return next((i for i, h in enumerate(table.header) if h.startswith(prefix)), None)


def joined(title: str, columns: Sequence[tuple[Table | None, str, str | None]]
           ) -> Table | None:
    """Columns of several tables, rows joined on their first cell: (table, header prefix,
    header shown instead of the prefix or None). None when no column is found."""
    picked: list[tuple[Table, int, str]] = []
    for t, prefix, shown in columns:
        i = column(t, prefix) if t is not None else None
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
    return Table(tuple(name for _, _, name in picked), tuple(rows), align=align,
                 caption=title)
