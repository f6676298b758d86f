"""Numbers on the console, rounded as the certificate rounds them (its own functions).

The one place the console turns a measured number into text: a value with U through the
certificate's `format_value_u` (U to two significant digits, the value to match), a value
without U to its stated significant digits (`format_sig`), fractions in ppm or % chosen as
the certificate chooses a column's unit (`rel_unit`). A magnitude goes through the
certificate's one rule for unresolved values (`present`): "value ± U" when it stands out of
its U (k = 2), else its upper limit "< L".
"""

from __future__ import annotations

from collections.abc import Sequence

from bench.core.progress import RELATIVE, Figure
from bench.report.certificate.rounding import RelUnit, format_sig, format_value_u, present, rel_unit


def relative_unit(figures: Sequence[Figure]) -> RelUnit:
    """One unit for all the fractions of one line, as for one column of the certificate."""
    return rel_unit(*[v for f in figures if f.unit == RELATIVE for v in (f.value, f.u)])


def figure_text(f: Figure, rel: RelUnit | None = None) -> str:
    """`value ± U unit`, or `value unit` without U."""
    scale, unit = 1.0, f.unit
    if f.unit == RELATIVE:
        rel = rel or relative_unit([f])
        scale, unit = rel.scale, rel.name
    if f.value is None:
        return "n/a"
    if f.magnitude:
        return present(f.value, f.u, scale).with_unit(unit)
    if f.u is not None:
        return format_value_u(f.value, f.u, scale, f.signed).joined(unit)
    text = format_sig(f.value * scale, f.digits, f.signed)
    return f"{text} {unit}" if unit else text


def figures_text(figures: Sequence[Figure]) -> str:
    rel = relative_unit(figures)
    return ", ".join(f"{f.name} = {figure_text(f, rel)}" if f.name else figure_text(f, rel)
                     for f in figures)
