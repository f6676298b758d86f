"""bench.analysis.coverage's t and chi-square quantiles equal scipy.stats' to the last bit.

They call the special functions scipy.stats' own ppf calls (so that a run's end need not
import scipy.stats, issue 62); a scipy release that computed its quantiles otherwise would
change the bench's figures' last digits, and this test would say so first.
"""

from __future__ import annotations

import pytest
from scipy.stats import chi2, t

from bench.analysis.coverage import COVERAGE_P, chi2_ppf, t_ppf

_NU = [1, 2, 3, 4, 5, 9, 17, 29, 100, 999, 5000, 9999, 10000, 2.5, 47.25, 1234.5678]
_Q = [0.025, 0.975, (1.0 + COVERAGE_P) / 2.0, 1.0 - 0.975, 0.5]


@pytest.mark.parametrize("nu", _NU)
def test_chi2_and_t_quantiles_are_scipy_stats_to_the_last_bit(nu: float) -> None:
    for q in _Q:
        assert chi2_ppf(q, nu) == float(chi2.ppf(q, nu)), (q, nu)
        assert t_ppf(q, nu) == float(t.ppf(q, nu)), (q, nu)


def test_an_integer_nu_gives_what_its_float_gives() -> None:
    for nu in (1, 4, 99):
        assert chi2_ppf(0.025, nu) == chi2_ppf(0.025, float(nu))
        assert t_ppf(0.975, nu) == t_ppf(0.975, float(nu))
