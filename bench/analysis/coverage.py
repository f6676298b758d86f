"""The coverage factor of every expanded uncertainty U the bench states (docs/method.md D1).

One rule, EA-4/02 M:2022 annex E: the combined standard uncertainty u_c = sqrt(sum u_i^2)
of a budget's contributions; its effective degrees of freedom nu_eff by Welch-Satterthwaite
(`welch_satterthwaite`, infinite for Type B terms); the coverage factor k the Student t
quantile for a coverage probability of 95.45 % at nu_eff truncated to the next lower integer,
to two decimals as EA-4/02 table E.1 states it (`coverage_factor`: 2.00 for infinite
nu_eff, 2.52 for 6, 3.31 for 3); U = k * u_c. A Type A term is s / sqrt(N) with its own
nu = N - 1 (or the pooled dof), never widened: the t-factor carries the few samples.

The analysis (bench/analysis/turns.py) and the report's budgets (bench/report/budget.py)
both take k from here, so a budget reproduces the U the analysis reports exactly.
The formula texts below are what the certificate's method section prints.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from decimal import ROUND_HALF_UP, Decimal

#: the coverage probability of k = 2 for a normal distribution (EA-4/02: "95.45 %")
COVERAGE_P = 0.9544997361036416
#: as the certificate and the DCC state it
COVERAGE_P_TEXT = "95.45 %"
#: k for infinite degrees of freedom
K_NORMAL = 2.0
#: nu_eff above this is printed and treated as infinite (k = 2.00 to two decimals)
DOF_INFINITE = 1e4

#: docs/method.md D1, rendered by the certificate's method section from here
COVERAGE_FORMULA = ("u_c = √(Σ u_i² + 2 Σ r_ij c_i u(x_i) c_j u(x_j));   ν_eff = u_c⁴ / "
                    "Σ (u_i⁴ / ν_i)  (Welch-Satterthwaite with that u_c, ν_i = ∞ for Type B);   "
                    "k = t_95.45 %(⌊ν_eff⌋) to two decimals;   U = k · u_c")
COVERAGE_RULE = ("Every U is k · u_c of its budget, k the Student t factor for 95.45 % at the "
                 "budget's effective degrees of freedom ν_eff (Welch-Satterthwaite, truncated "
                 "to an integer, k to two decimals as EA-4/02 M:2022 table E.1): k = 2.00 "
                 "where ν_eff is infinite or very large, larger where a Type A term rests on "
                 "few values (ν_eff = 6: k = 2.52; ν_eff = 3: k = 3.31). A Type A term is "
                 "s/√N with ν = N − 1 (or the pooled degrees of freedom), not widened: the "
                 "t-factor carries the few values.")


def welch_satterthwaite(terms: Iterable[tuple[float, float | None]],
                        uc: float | None = None) -> float | None:
    """nu_eff = u_c^4 / sum(u_i^4 / nu_i) over (u_i, nu_i) (EA-4/02 eq. E.1, docs/method.md
    D1); nu_i None is infinite. `uc` is the combined standard uncertainty when it is not
    sqrt(sum u_i^2): a budget with correlated inputs (GUM 5.2.2) gives its own, and the
    numerator is that u_c. None (infinite) when no term has finite dof."""
    pairs = [(abs(u), nu) for u, nu in terms]
    uc2 = sum(u * u for u, _ in pairs) if uc is None else uc * uc
    denom = sum(u ** 4 / nu for u, nu in pairs if nu is not None and nu > 0 and u > 0)
    if denom == 0 or uc2 == 0:
        return None
    return uc2 * uc2 / denom


def t_ppf(q: float, nu: float) -> float:
    """Student's t quantile q at nu degrees of freedom: `scipy.stats.t.ppf(q, nu)` to the
    last bit (that is `scipy.special.stdtrit(nu, q)`, times scale 1 plus loc 0), without
    importing scipy.stats: ~0.6 s a process, paid at the end of every run, when the
    result is written. tests/test_quantiles.py holds both to scipy.stats'."""
    from scipy.special import stdtrit

    return float(stdtrit(nu, q))


def chi2_ppf(q: float, nu: float) -> float:
    """The chi-square quantile q at nu degrees of freedom: `scipy.stats.chi2.ppf(q, nu)`
    to the last bit (`2 * scipy.special.gammaincinv(nu / 2, q)`), without scipy.stats
    (see `t_ppf`)."""
    from scipy.special import gammaincinv

    return float(2 * gammaincinv(nu / 2, q))


def coverage_factor(nu_eff: float | None) -> float:
    """k = t_p(floor(nu_eff)), p = 95.45 %, rounded half-up to two decimals (EA-4/02 E.1,
    docs/method.md D1); 2.0 for infinite nu_eff."""
    if nu_eff is None or not math.isfinite(nu_eff) or nu_eff > DOF_INFINITE:
        return K_NORMAL
    nu = max(math.floor(nu_eff + 1e-9), 1)
    k = t_ppf((1.0 + COVERAGE_P) / 2.0, nu)     # two-sided: the upper quantile
    return float(Decimal(repr(k)).quantize(Decimal("0.01"), rounding=ROUND_HALF_UP))


def expanded(terms: Iterable[tuple[float, float | None]]) -> tuple[float, float | None, float,
                                                                  float]:
    """(u_c, nu_eff, k, U) of standard-uncertainty contributions (u_i, nu_i) (docs/method.md
    D1): the one place U = k(nu_eff) * u_c is computed."""
    items = list(terms)
    uc = math.sqrt(sum(u * u for u, _ in items))
    nu = welch_satterthwaite(items)
    k = coverage_factor(nu)
    return uc, nu, k, k * uc
