"""Uncertainty budgets in the form of EA-4/02 M:2022 (section 4 and its examples): for each
input quantity its estimate, standard uncertainty, distribution, sensitivity coefficient,
contribution to the standard uncertainty of the result and degrees of freedom; then the
combined standard uncertainty, the effective degrees of freedom (Welch-Satterthwaite,
EA-4/02 annex E), the coverage factor k = t_95.45(nu_eff) and U = k u_c, by the one rule
of bench/analysis/coverage.py (docs/method.md D1) that the analysis computes with.

The procedure kinds build their budgets from the analysis results (procedures/*/budgets.py)
and add them to result.json; the certificate and the DCC print what is there. A budget
whose combined uncertainty does not reproduce the U the analysis reports says so: the
reader sees both, nothing is adjusted to agree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import msgspec

from bench.analysis.coverage import COVERAGE_P, coverage_factor, welch_satterthwaite

NORMAL = "normal"
RECTANGULAR = "rectangular"
STUDENT_T = "Student t"
CHI_SQUARE = "chi-square (a standard deviation)"
AGREE_REL = 0.05      # a budget "reproduces" the reported U within 5 %


@dataclass(frozen=True)
class Term:
    """One input quantity X_i of a budget."""

    quantity: str                  # what it is, with its symbol
    estimate: float | None         # x_i (None: a correction of zero, or not a number)
    ustd: float                    # u(x_i), in the input's own unit
    distribution: str
    sensitivity: float             # c_i = df/dx_i, result unit per input unit
    dof: float | None = None       # nu_i; None for infinite (Type B, or very many)
    unit: str = ""                 # the input's unit

    @property
    def contribution(self) -> float:
        """u_i(y) = |c_i| u(x_i), in the result's unit."""
        return abs(self.sensitivity) * self.ustd

    @property
    def signed_contribution(self) -> float:
        """c_i u(x_i): the sign matters where two inputs are correlated (GUM 5.2.2)."""
        return self.sensitivity * self.ustd

    def record(self) -> TermRecord:
        """The term as result.json states it, typed (`TermRecord`)."""
        return TermRecord(quantity=self.quantity, estimate=self.estimate, unit=self.unit,
                          ustd=self.ustd, distribution=self.distribution,
                          sensitivity=self.sensitivity, contribution_ustd=self.contribution,
                          dof=self.dof)


@dataclass(frozen=True)
class Budget:
    """The budget of one reported quantity `key` (its result.json key)."""

    quantity: str
    key: str
    unit: str
    estimate: float | None
    terms: tuple[Term, ...]
    reported_U: float | None = None      # the U the analysis reports for it
    note: str = ""
    #: (i, j, r_ij): inputs i and j (indices into terms) correlated with coefficient r_ij
    correlations: tuple[tuple[int, int, float], ...] = ()

    @property
    def ustd(self) -> float:
        """u_c(y)^2 = sum (c_i u(x_i))^2 + 2 sum_{i<j} c_i c_j u(x_i) u(x_j) r(x_i, x_j)
        (GUM 5.2.2 eq. 16, docs/method.md D1; EA-4/02 eq. 4.3 where no r is stated)."""
        s = [t.signed_contribution for t in self.terms]
        var = sum(x * x for x in s) + 2.0 * sum(r * s[i] * s[j]
                                                for i, j, r in self.correlations)
        return math.sqrt(max(var, 0.0))

    @property
    def dof_eff(self) -> float | None:
        """nu_eff = u_c^4 / sum(u_i^4 / nu_i) (EA-4/02 eq. E.1, docs/method.md D1), u_c with
        the correlations (GUM 5.2.2); None for infinite."""
        return welch_satterthwaite(((t.contribution, t.dof) for t in self.terms), self.ustd)

    @property
    def k(self) -> float:
        """k = t_95.45(nu_eff) to two decimals (docs/method.md D1)."""
        return coverage_factor(self.dof_eff)

    @property
    def U(self) -> float:  # noqa: N802 - the symbol of the expanded uncertainty
        """U = k u_c (docs/method.md D1)."""
        return self.k * self.ustd

    @property
    def reproduces(self) -> bool | None:
        """Does the budget give the U the analysis reports (within AGREE_REL)?"""
        if self.reported_U is None or self.reported_U <= 0:
            return None
        return abs(self.U - self.reported_U) <= AGREE_REL * self.reported_U

    def record(self) -> BudgetRecord:
        """The budget as result.json states it, its derived figures (u_c, nu_eff, k, U)
        computed once here and written out (`BudgetRecord`)."""
        return BudgetRecord(
            quantity=self.quantity, key=self.key, unit=self.unit, estimate=self.estimate,
            terms=tuple(t.record() for t in self.terms), combined_ustd=self.ustd,
            dof_eff=self.dof_eff, coverage_factor=self.k, coverage_probability=COVERAGE_P,
            U_budget=self.U, U_reported=self.reported_U, reproduces_reported_U=self.reproduces,
            note=self.note, correlations=tuple(Correlation(terms=(i, j), r=r)
                                               for i, j, r in self.correlations))


# -- the budget as result.json holds it, typed: a kind's result model (msgspec Structs, issue
# 60) carries these, so msgspec decodes and encodes them with the rest of the model; the field
# order is result.json's key order (the bytes the dict writers above give).

class TermRecord(msgspec.Struct, frozen=True, kw_only=True):
    """One input quantity of a budget, as result.json states it."""

    quantity: str
    estimate: float | None
    unit: str
    ustd: float
    distribution: str
    sensitivity: float
    contribution_ustd: float
    dof: int | float | None

    def term(self) -> Term:
        return Term(self.quantity, self.estimate, self.ustd, self.distribution,
                    self.sensitivity, self.dof, self.unit)


class Correlation(msgspec.Struct, frozen=True, kw_only=True):
    """Inputs `terms` (two indices into the budget's terms) correlated with r."""

    terms: tuple[int, int]
    r: float


class BudgetRecord(msgspec.Struct, frozen=True, kw_only=True, omit_defaults=True):
    """A budget as result.json states it: inputs and the figures derived from them."""

    quantity: str
    key: str
    unit: str
    estimate: float | None
    terms: tuple[TermRecord, ...]
    combined_ustd: float
    dof_eff: float | None
    coverage_factor: float
    coverage_probability: float
    U_budget: float          # noqa: N815 - result.json's key
    U_reported: float | None  # noqa: N815 - result.json's key
    reproduces_reported_U: bool | None  # noqa: N815 - result.json's key
    note: str
    correlations: tuple[Correlation, ...] = ()

    def __post_init__(self) -> None:
        n = len(self.terms)
        if any(not (0 <= i < n and 0 <= j < n) for c in self.correlations for i, j in
               (c.terms,)):
            raise ValueError(f"a correlation names a term outside the {n} terms")

    def budget(self) -> Budget:
        """The budget to compute with (its k, U, nu_eff from the stated inputs)."""
        return Budget(self.quantity, self.key, self.unit, self.estimate,
                      tuple(t.term() for t in self.terms), self.U_reported, self.note,
                      tuple((c.terms[0], c.terms[1], c.r) for c in self.correlations))


def num(x: object) -> float | None:
    """A finite number (None for text, a bool, None, NaN): a budget's optional figure."""
    if isinstance(x, bool) or not isinstance(x, int | float):
        return None
    return float(x) if math.isfinite(x) else None
