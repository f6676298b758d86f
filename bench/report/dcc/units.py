"""D-SI unit strings (D-SI 2.2.1, SI brochure 9th edition) used in the DCC, and their check.

The XSD types `si:unit` as a plain string, so schema validation accepts any text there;
a misspelt unit would pass unnoticed. Every unit string in a DCC we write or read is
therefore parsed with PTB's `dsiUnits` package (import name `dsi_unit`), which knows the
D-SI grammar (`\\prefix\\unit\\tothe{n}`) and the unit and prefix names.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable
from functools import lru_cache

from dsi_unit import DsiUnit

DEG_PER_S = r"\degree\second\tothe{-1}"
DEG_PER_H = r"\degree\hour\tothe{-1}"
DEG = r"\degree"
ONE = r"\one"            # a relative value (a plain fraction, never % or ppm)
HERTZ = r"\hertz"
SECOND = r"\second"
VOLT = r"\volt"
CELSIUS = r"\degreecelsius"
PERCENT = r"\percent"
HECTOPASCAL = r"\hecto\pascal"

#: the unit of a result key by its suffix (the project's names carry their unit)
BY_SUFFIX: dict[str, str] = {
    "dps": DEG_PER_S, "dph": DEG_PER_H, "deg": DEG, "rel": ONE, "hz": HERTZ, "s": SECOND,
    "v": VOLT, "c": CELSIUS, "pct": PERCENT, "hpa": HECTOPASCAL,
}


@lru_cache(maxsize=512)
def unit_problem(unit: str) -> str | None:
    """Why `unit` is not a valid D-SI unit string, or None when it is (a DCC repeats a
    handful of units hundreds of times, so each is parsed once)."""
    if not unit or unit != unit.strip():
        return f"D-SI unit {unit!r}: empty or padded with blanks"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # dsiUnits warns and also records the reason
        parsed = DsiUnit(unit)
    if parsed.valid:
        return None
    reasons = "; ".join(str(w) for w in getattr(parsed, "warnings", []) or []) or "not D-SI"
    return f"D-SI unit {unit!r}: {reasons}"


def unit_list_problems(units: Iterable[str]) -> list[str]:
    """Problems of each unit in a whitespace-separated `si:unitXMLList` (or single units)."""
    return [p for text in units for u in text.split() for p in (unit_problem(u),) if p]
