"""Rounding of a result and its expanded uncertainty for printing (GUM 7.2.6, EA-4/02).

U is printed with at most two significant digits and the value is rounded to the same
decimal place. EA-4/02 M:2022 asks for U to be rounded up, allowing the usual rounding
only when it lowers U by no more than 5 %; with two digits the usual rounding never lowers
U by more than 5 %, but the rule is kept general for `sig = 1`.

Rounding is done in decimal on the shortest repr of the float, so 0.285 rounds to 0.29 as
a reader doing it by hand expects, not to 0.28 as binary floating point would.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from decimal import ROUND_CEILING, ROUND_FLOOR, ROUND_HALF_UP, Decimal

MINUS = "\u2212"  # the typographic minus sign


def _quantize(x: float, decimals: int, rounding: str = ROUND_HALF_UP) -> Decimal:
    return Decimal(repr(float(x))).quantize(Decimal(1).scaleb(-decimals), rounding=rounding)


def _text(d: Decimal, decimals: int, signed: bool = False) -> str:
    """Fixed-point text of a quantized decimal; never '-0.00'; a true minus sign."""
    if d == 0:
        d = abs(d)
    s = f"{d:.{max(decimals, 0)}f}"
    if s.startswith("-"):
        return MINUS + s[1:]
    return ("+" + s) if signed and d > 0 else s


def round_u(u: float, sig: int = 2) -> tuple[Decimal, int]:
    """U rounded to at most `sig` significant digits, and the number of decimals kept.

    `decimals` may be negative (U = 1234 -> 1200, decimals -2).
    """
    if not math.isfinite(u) or u <= 0:
        raise ValueError(f"an expanded uncertainty must be finite and > 0, got {u!r}")
    exponent = math.floor(math.log10(u))
    decimals = sig - 1 - exponent
    nearest = _quantize(u, decimals)
    if nearest < Decimal(repr(float(u))) and (u - float(nearest)) / u > 0.05:
        nearest = _quantize(u, decimals, ROUND_CEILING)  # EA-4/02: round up beyond 5 %
    if nearest >= Decimal(10) ** (exponent + 1):
        decimals -= 1  # 0.0997 -> 0.10, two digits, not 0.100
        nearest = _quantize(float(nearest), decimals)
    return nearest, decimals


@dataclass(frozen=True)
class Rounded:
    """A value and its U as printed, both in the same unit and to the same decimal."""

    value: str
    u: str | None

    def joined(self, unit: str = "") -> str:
        tail = f" {unit}" if unit else ""
        return f"{self.value} ± {self.u}{tail}" if self.u else f"{self.value}{tail}"


def format_value_u(value: float | None, u: float | None, scale: float = 1.0,
                   signed: bool = False, sig_without_u: int = 4) -> Rounded:
    """Value and U (k = 2) multiplied by `scale` (e.g. 100 for %) and rounded to match.

    Without a usable U the value keeps `sig_without_u` significant digits and U is None.
    """
    if value is None or not math.isfinite(value):
        return Rounded("n/a", None)
    v = value * scale
    if u is not None and math.isfinite(u) and u > 0:
        ur, decimals = round_u(u * scale)
        return Rounded(_text(_quantize(v, decimals), decimals, signed), _text(ur, decimals))
    return Rounded(format_sig(v, sig_without_u, signed), None)


def format_limit(x: float, sig: int = 2) -> tuple[str, int]:
    """An upper limit to `sig` significant digits, rounded up (a limit is never lowered);
    returns the text and its number of decimals. Float noise below 1e-9 is ignored."""
    if not math.isfinite(x) or x <= 0:
        raise ValueError(f"an upper limit must be finite and > 0, got {x!r}")
    exponent = math.floor(math.log10(x))
    decimals = sig - 1 - exponent
    value = _quantize(x * (1 - 1e-9), decimals, ROUND_CEILING)
    if value >= Decimal(10) ** (exponent + 1):
        decimals -= 1
        value = _quantize(float(value), decimals)
    return _text(value, decimals), decimals


def format_fixed(x: float, decimals: int, signed: bool = False) -> str:
    """`x` rounded (half up, in decimal) to `decimals` places; negative places allowed."""
    return _text(_quantize(x, decimals), decimals, signed)


def format_sig(x: float, sig: int = 4, signed: bool = False) -> str:
    """`x` with `sig` significant digits in fixed point (scientific when very large/small)."""
    if x is None or not math.isfinite(x):
        return "n/a"
    if x == 0:
        return "0"
    exponent = math.floor(math.log10(abs(x)))
    if exponent < -6 or exponent > 9:
        s = f"{x:.{sig - 1}e}".replace("-", MINUS)
        return ("+" + s) if signed and x > 0 else s
    decimals = sig - 1 - exponent
    return _text(_quantize(x, decimals), decimals, signed)


@dataclass(frozen=True)
class RelUnit:
    """How a column of relative values is printed: % or ppm."""

    name: str
    scale: float


PERCENT = RelUnit("%", 100.0)
PPM = RelUnit("ppm", 1e6)


def rel_unit(*magnitudes: float | None) -> RelUnit:
    """ppm when every magnitude of the column is below 0.01 % (1e-4), else %.

    One unit per column, so a reader compares rows without converting.
    """
    finite = [abs(m) for m in magnitudes if m is not None and math.isfinite(m)]
    if finite and max(finite) < 1e-4:
        return PPM
    return PERCENT


# -- one rule for quantities that may not be resolved (certificate, console summary) --------

RESOLUTION_K = 2.0
#: docs/method.md D2 states this text verbatim (tests/test_budget_recompute.py checks it)
RESOLUTION_RULE = (
    "One rule for every magnitude (an amplitude, a standard deviation, a floor-corrected "
    "figure): it is resolved when the lower end of its coverage interval (about 95 %) lies "
    "above its floor, zero where it has none (the timing floor for the σ of the per-turn "
    "rates; the FOG's noise floor for the raw intra-turn instability and the FOG's figures "
    "over 1° and 10°; for a harmonic or the mains tone its interval a ± c·u(a), c the "
    "radius of the joint detection test of A4). A resolved magnitude is printed 'value ± U' when its "
    "interval is symmetric (then value − U > floor) and 'value [lower, upper]' when it is "
    "not (a standard deviation from few values, a floor-corrected figure). Otherwise it is "
    "printed '< L', L the upper end of its interval as a one-sided limit, rounded up and "
    "never below the floor; its phase, if any, is printed '—'. No value or U is printed "
    "below its floor. Floors, settings, nominal values and the budget's inputs are stated "
    "as what they are, without a U of their own.")
NOT_STATED = "—"


@dataclass(frozen=True)
class Presented:
    """A magnitude as printed under the one rule: 'value ± U', 'value [lower, upper]' or
    '< L'."""

    text: str
    resolved: bool
    limit: float | None = None  # the one-sided upper limit, unscaled, when not resolved

    def with_unit(self, unit: str) -> str:
        if not unit or self.text == NOT_STATED:
            return self.text
        if "[" in self.text:            # '0.05 [0.02, 0.20]' -> '0.05 ppm [0.02, 0.20]'
            head, tail = self.text.split(" [", 1)
            return f"{head} {unit} [{tail}"
        return f"{self.text} {unit}"


def is_resolved(value: float | None, u_expanded: float | None,
                k: float = RESOLUTION_K, floor: float | None = None) -> bool:
    """The one rule (docs/method.md D2) for a symmetric interval: |value| - U > floor (0
    without one). Without a usable U nothing is resolved, since nothing shows that the
    value stands out of its own scatter."""
    if value is None or u_expanded is None:
        return False
    if not (math.isfinite(value) and math.isfinite(u_expanded)) or u_expanded <= 0:
        return False
    return abs(value) - u_expanded * k / RESOLUTION_K > (floor or 0.0)


def format_interval(value: float, lower: float, upper: float, scale: float = 1.0
                    ) -> str:
    """'value [lower, upper]' (docs/method.md D2): the decimals of the wider side's
    distance to two significant digits, or more where a lower end above zero needs them for
    two significant digits of its own (0.0299 is printed 0.029, not 0.02); the lower end
    rounded down and the upper end up (an interval is never narrowed)."""
    v, lo, hi = value * scale, lower * scale, upper * scale
    _, decimals = round_u(max(hi - v, v - lo, abs(v) * 1e-12, 1e-300))
    if lo > 0 and math.isfinite(lo):
        decimals = max(decimals, 1 - math.floor(math.log10(lo)))
    return (f"{_text(_quantize(v, decimals), decimals)} "
            f"[{_text(_quantize(lo, decimals, ROUND_FLOOR), decimals)}, "
            f"{_text(_quantize(hi, decimals, ROUND_CEILING), decimals)}]")


def present(value: float | None, u_expanded: float | None, scale: float = 1.0, *,
            upper: float | None = None, resolved: bool | None = None,
            signed: bool = False, interval: tuple[float, float] | None = None,
            floor: float | None = None) -> Presented:
    """A magnitude and its U as the certificate and the console print it (docs/method.md
    D2).

    `interval` is its asymmetric coverage interval (lower, upper): a resolved value is then
    printed 'value [lower, upper]'. `upper` is a one-sided upper limit computed elsewhere
    (e.g. a floor-corrected figure's); without it the limit is |value| + U (or the
    interval's upper end). `resolved` overrides the symmetric test when the caller has the
    interval's (a sigma against the counter's timing floor). A limit is never printed below
    `floor`. A value with no usable U is never printed bare: it is printed as its limit
    when one is given, else as '—'.
    """
    if resolved is None:
        resolved = (interval[0] > (floor or 0.0) if interval is not None
                    else is_resolved(value, u_expanded, floor=floor))
    if resolved and value is not None and interval is not None:
        return Presented(format_interval(value, interval[0], interval[1], scale), True)
    if resolved and value is not None and u_expanded is not None:
        return Presented(format_value_u(value, u_expanded, scale, signed).joined(), True)
    limit = upper
    if limit is None and interval is not None:
        limit = interval[1]
    if limit is None and value is not None and u_expanded is not None \
            and math.isfinite(value) and math.isfinite(u_expanded) and u_expanded > 0:
        limit = abs(value) + u_expanded
    if limit is not None and floor is not None and math.isfinite(floor):
        limit = max(limit, floor)       # D2: never below the floor
    if limit is None or not math.isfinite(limit) or limit <= 0:
        return Presented(NOT_STATED, False)
    return Presented(f"< {format_limit(limit * scale)[0]}", False, limit)


def present_phase(phase: float | None, u_expanded: float | None, amplitude_resolved: bool,
                  signed: bool = True) -> str:
    """A phase is printed only with a resolved amplitude; else '—' (it means nothing)."""
    if not amplitude_resolved or phase is None or u_expanded is None \
            or not math.isfinite(u_expanded) or u_expanded <= 0:
        return NOT_STATED
    return format_value_u(phase, u_expanded, signed=signed).joined()


def present_std(value: float | None, u_expanded: float | None, scale: float = 1.0, *,
                lower: float | None, upper: float | None, floor: float | None,
                resolved: bool | None) -> Presented:
    """A standard deviation from few values under the one rule (docs/method.md A2, D2), as
    the certificate, the DCC and the station state it: resolved when its chi-square lower
    limit lies above its floor (the analysis's `resolved`; without it, value - U > floor),
    printed as its interval 'value [lower, upper]'; else '< L', L its one-sided upper limit,
    never below the floor. Never a normal 'value ± U' when the interval is known."""
    if resolved is None:
        resolved = (value is not None and u_expanded is not None
                    and value - u_expanded > (floor if floor is not None else 0.0))
    interval = (lower, upper) if lower is not None and upper is not None else None
    return present(value, u_expanded, scale, resolved=bool(resolved), upper=upper,
                   interval=interval, floor=floor)
