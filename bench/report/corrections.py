"""The instrument corrections a result applied (issue 58), typed, and the certificate's
words for them.

A run folder's `corrections.json` (written by `bench impact` in a copy, or by a corrected
re-issue in the run folder itself) lists corrections; the kind's analysis applies those it
models and states the list in result.json's `corrections`. Every reader of that list
(the certificate, the DCC, the corrected re-issue) reads it here, where its keys are
spelled once (decoded by bench/report/result_frame.py, the frame's codec): the PDF, HTML
and DCC then say the same words.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class Correction:
    """One correction: the item's place on the stand, its serial and model, the quantity
    corrected, the value and its expanded U (k = 2: a calibration certificate's), where
    the value came from, and why it was applied."""

    where: str
    serial: str | None
    model: str | None
    quantity: str
    value: float | None
    value_U: float | None
    source: str | None
    reason: str | None

    def same_as(self, other: Correction) -> bool:
        """The same correction of the same item (why it was applied aside)."""
        return (self.where, self.serial, self.quantity, self.value, self.value_U) == \
            (other.where, other.serial, other.quantity, other.value, other.value_U)


def _g(x: float | None) -> str:
    return "not stated" if x is None else f"{x:.3g}"


def statements(corrections: Sequence[Correction]) -> list[str]:
    """The certificate's words for each correction the result applied (`ResultFrame.
    corrections`; PDF, HTML and DCC alike): the item, the value with its U, what was done
    with it and why."""
    out = []
    for c in corrections:
        item = f"{c.model or 'model not stated'}, serial {c.serial or 'not stated'}"
        if c.quantity == "timebase_offset_rel":
            what = f"the counter at {c.where} ({item})"
            value = f"time-base offset e = {_g(c.value)} (U = {_g(c.value_U)}, k = 2)"
            done = ("every interval it timed was divided by 1 + e before the analysis, which "
                    "moves each rate error by about +e and the FOG scale k by about -e k; "
                    "u(e) = U/2 is a row of the rate error's uncertainty budget "
                    "(docs/method.md A1, a counter's time-base correction)")
        else:
            what = f"the instrument at {c.where} ({item})"
            value = f"{c.quantity} = {_g(c.value)} (U = {_g(c.value_U)}, k = 2)"
            done = ("applied by the analysis as docs/method.md states for it; its u = U/2 "
                    "is a row of the budgets it enters")
        text = (f"Correction applied: {what} had a {value}"
                + (f", the {c.source}" if c.source else "") + f"; {done}.")
        if c.reason:
            text += f" Why: {c.reason}."
        out.append(text)
    return out
