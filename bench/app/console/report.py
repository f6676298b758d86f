"""The end-of-run summary as text: tables aligned under their headers, verdicts marked.

The figures come from the certificate (`bench/app/summary.py` cuts them from its document);
this module only lays them out, for every console alike.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass

STATEMENT_FIELD = "Statement of conformity"
VERDICT_STYLES = {"PASS": "bold green", "FAIL": "bold red", "INCOMPLETE": "bold yellow",
                  "CONDITIONAL": "bold yellow"}


@dataclass(frozen=True)
class SummaryTable:
    """A table of the summary: the certificate's header texts and cells, as printed."""

    title: str
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    align: str


@dataclass(frozen=True)
class Summary:
    tables: tuple[SummaryTable, ...]
    fields: tuple[tuple[str, str], ...]   # single figures (the platform azimuth)
    statement: str                        # the certificate's statement of conformity
    verdict: str                          # PASS, FAIL, INCOMPLETE


def _cell(text: str, width: int, align: str) -> str:
    if align == "r":
        return text.rjust(width)
    if align == "c":
        return text.center(width)
    return text.ljust(width)


def table_lines(t: SummaryTable, gap: int = 2) -> list[str]:
    """The table as aligned text: every column as wide as its widest cell or header."""
    widths = [max(len(h), *(len(r[i]) for r in t.rows)) for i, h in enumerate(t.header)]
    sep = " " * gap
    head = sep.join(_cell(h, w, a) for h, w, a in zip(t.header, widths, t.align, strict=True))
    out = [t.title, head.rstrip(), "-" * len(head.rstrip())]
    for row in t.rows:
        out.append(sep.join(_cell(c, w, a) for c, w, a in
                            zip(row, widths, t.align, strict=True)).rstrip())
    return out


def summary_lines(summary: Summary) -> list[str]:
    out: list[str] = []
    for t in summary.tables:
        out += [""] + table_lines(t)
    if summary.fields:
        out.append("")
        out += [f"{k}: {v}" for k, v in summary.fields]
    out.append("")
    if summary.statement:
        out.append(f"{STATEMENT_FIELD}: {summary.statement}")
    out.append(f"verdict: {summary.verdict}")
    return out


def verdict_spans(line: str) -> Iterable[tuple[int, int, str]]:
    """Where a verdict word sits in a summary line, and its style (for a terminal)."""
    for word, style in VERDICT_STYLES.items():
        for m in re.finditer(rf"\b{word}\b", line):
            yield m.start(), m.end(), style


def print_summary(summary: Summary, write: Callable[[str], None],
                  styled: Callable[[str, list[tuple[int, int, str]]], None] | None = None
                  ) -> None:
    """Print through `write` (plain text), or `styled` (a terminal: verdicts coloured)."""
    for line in summary_lines(summary):
        spans = list(verdict_spans(line))
        if styled is not None and spans:
            styled(line, spans)
        else:
            write(line)
