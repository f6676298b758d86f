"""The one rule for magnitudes that may not be resolved (certificate and console share it).

Truth is hand-derived: the k = 2 test |x| > U, the one-sided limit |x| + U rounded up to
two significant digits, and '—' for a phase of an unresolved amplitude.
"""

from __future__ import annotations

import random
from decimal import Decimal

from bench.report.certificate.rounding import (
    MINUS,
    NOT_STATED,
    format_interval,
    format_limit,
    is_resolved,
    present,
    present_phase,
)


def test_k2_test_stated_once() -> None:
    assert is_resolved(3.0e-6, 2.9e-6)
    assert not is_resolved(2.9e-6, 2.9e-6)       # at U: consistent with zero
    assert not is_resolved(1.0, None)             # no U: nothing shows it stands out
    assert not is_resolved(1.0, 0.0)


def test_resolved_prints_value_and_u() -> None:
    p = present(8.683e-4, 7.8e-6, 100.0)
    assert p.resolved and p.text == "0.08683 ± 0.00078"


def test_unresolved_prints_one_sided_limit_rounded_up() -> None:
    # harmonic 3 of the demo: 0.00030 % ± 0.00075 % -> limit 0.00105 % -> '< 0.0011'
    p = present(3.0e-6, 7.5e-6, 100.0)
    assert not p.resolved
    assert p.text == "< 0.0011"
    assert abs(p.limit - 1.05e-5) < 1e-18


def test_stated_limit_and_forced_unresolved() -> None:
    # a sigma at its timing floor: the caller says 'not resolved' though sigma > U
    p = present(8.9e-9, 7.3e-9, 1e6, resolved=False, upper=2.1e-8)
    assert p.text == "< 0.021" and not p.resolved


def test_never_a_bare_value() -> None:
    assert present(1.0e-6, None).text == NOT_STATED
    assert present(1.0e-6, None, upper=3.0e-6, scale=1e6).text == "< 3.0"
    assert present(None, 1.0).text == NOT_STATED


def test_phase_only_with_a_resolved_amplitude() -> None:
    assert present_phase(-180.0, 180.0, False) == NOT_STATED
    assert present_phase(40.37, 0.52, True) == "+40.37 ± 0.52"


def _dec(text: str) -> Decimal:
    return Decimal(text.replace(MINUS, "-"))


def test_rounding_never_moves_a_bound_inwards() -> None:
    """Issue 56: an interval's printed lower end is at or below the true one and above zero
    when it is (two significant digits at least: 0.0299 is 0.029, not 0.02), its upper end
    at or above the true one; a printed limit L is never below the L computed. Drawn over
    twelve decades, hand-checked cases first."""
    assert format_interval(5.275e-8, 2.988e-8, 1.967e-7, 1e6) == "0.053 [0.029, 0.197]"
    assert format_limit(1.0023e-3 * 100)[0] == "0.11"
    rng = random.Random(56)
    for _ in range(4000):
        lo = 10.0 ** rng.uniform(-9, 3)
        value = lo * rng.uniform(1.0, 4.0)
        hi = value * rng.uniform(1.0, 6.0)
        text = format_interval(value, lo, hi)
        _, lo_t, hi_t = text.replace("[", "").replace("]", "").replace(",", "").split()
        assert _dec(lo_t) <= Decimal(repr(lo)) and _dec(hi_t) >= Decimal(repr(hi)), text
        assert _dec(lo_t) > 0, text
        digits = _dec(lo_t).adjusted() - _dec(lo_t).as_tuple().exponent + 1
        assert digits >= 2, text                     # two significant digits of its own
        limit = 10.0 ** rng.uniform(-9, 3)
        assert Decimal(format_limit(limit)[0]) >= Decimal(repr(limit)) * Decimal(
            1 - 1e-9), limit
        p = present(value, hi - value, upper=hi, resolved=False)
        assert p.limit == hi and Decimal(p.text[2:]) >= Decimal(repr(hi)) * Decimal(1 - 1e-9)
