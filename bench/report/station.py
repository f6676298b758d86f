"""The station's result tables, worded by the certificate's rounding rule, and what the
station asks a procedure kind about its results (`StationParts`, neutral answers).

The run pages (bench/app/station) print a kind's results the way its certificate does:
U to two significant digits, the value to the same decimal, one unit per column. The
words and the rounding are here, one layer below the kinds, so a kind's `station` part
builds its own tables with them and the station names none of a kind's quantities.
Nothing here names a procedure kind.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from bench.core.events import LiveRow
from bench.report.certificate.rounding import MINUS, RelUnit, format_value_u, rel_unit
from bench.report.result_frame import ResultFrame
from drivers.json_types import JsonLike, JsonValue

#: a table as the run page's script draws it (station.js `table`): id, caption, header,
#: and rows of {cells, class}
PageTable = dict[str, JsonLike]


def page_table(tid: str, caption: str, header: Sequence[str],
               rows: Sequence[tuple[Sequence[str], str]]) -> PageTable:
    """A table: its id, caption, header, and each row's cells with its class."""
    return {"id": tid, "caption": caption, "header": list(header),
            "rows": [{"cells": list(cells), "class": cls} for cells, cls in rows]}


def number(v: JsonValue) -> float | None:
    """A finite number from the state or a result (None for anything else)."""
    if not isinstance(v, int | float | str):
        return None
    try:
        x = float(v)
    except ValueError:
        return None
    return x if math.isfinite(x) else None


def rate_text(v: JsonValue) -> str:
    """A set rate, signed, with the typographic minus the certificate prints."""
    if not isinstance(v, int | float | str):
        return "-"
    try:
        return f"{float(v):+g}".replace("-", MINUS)
    except ValueError:
        return "-"


def value_u(value: JsonValue, u: JsonValue, scale: float = 1.0,
            signed: bool = False) -> str:
    """'value ± U' by the certificate's rule; a value without a usable U keeps four
    significant digits and says so."""
    r = format_value_u(number(value), number(u), scale, signed=signed)
    if r.u is None:
        return "-" if r.value == "n/a" else f"{r.value} (no U)"
    return r.joined()


def column_unit(*values: JsonValue) -> RelUnit:
    """One unit per column (ppm below 0.01 %, else %), as the certificate chooses it."""
    return rel_unit(*[number(v) for v in values])


class StationParts:
    """The station's questions to a procedure kind about its results, with neutral
    answers: no live table, no tables of its own (the pages list its declared figures)."""

    def live_table(self, rows: Sequence[LiveRow]) -> PageTable | None:
        """The first looks as they come (none)."""
        return None

    def last_look(self, row: LiveRow) -> str | None:
        """The newest first look in one line (none)."""
        return None

    def result_tables(self, frame: ResultFrame) -> list[PageTable]:
        """result.json's own tables (none: the page lists the declared figures)."""
        return []

    def result_rows(self, frame: ResultFrame) -> list[LiveRow]:
        """result.json's figures per row (none)."""
        return []
