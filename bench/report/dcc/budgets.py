"""The uncertainty budgets (EA-4/02 form, bench.report.budget) in the DCC, as the PDF prints them:
one dcc:result per budget, one dcc:list per input quantity (estimate, standard
uncertainty, sensitivity coefficient, contribution, degrees of freedom; the distribution
in its name), then the combined standard uncertainty, nu_eff and U.
"""

from __future__ import annotations

from collections.abc import Sequence

from lxml import etree

from bench.analysis.coverage import DOF_INFINITE
from bench.report.budget_codec import BudgetSite
from bench.report.dcc import vocab as V
from bench.report.dcc.units import DEG, DEG_PER_H, DEG_PER_S, ONE
from bench.report.dcc.xml import el, ident, name, quantity, text_el

DEG_PER_S_PER_H = r"\degree\second\tothe{-1}\hour\tothe{-1}"
UNITS = {"1": ONE, "deg/s": DEG_PER_S, "deg/h": DEG_PER_H, "deg": DEG, "s": r"\second",
         "V/deg": r"\volt\degree\tothe{-1}", "deg/s/h": DEG_PER_S_PER_H}
#: D-SI unit of a sensitivity coefficient: (result unit, input unit) -> unit
SENSITIVITY_UNITS = {("1", "1"): ONE, ("deg/s", "deg/s"): ONE, ("deg/h", "deg/h"): ONE,
                     ("deg", "deg"): ONE, ("deg", "1"): DEG,
                     ("1", "deg/s"): r"\second\degree\tothe{-1}", ("deg", "deg/h"): r"\hour",
                     ("deg/h", "1"): DEG_PER_H, ("deg/h", "deg"): r"\hour\tothe{-1}",
                     ("deg/h", "s"): r"\degree\hour\tothe{-1}\second\tothe{-1}",
                     ("deg/h", "V/deg"): r"\degree\tothe{2}\volt\tothe{-1}\hour\tothe{-1}",
                     ("deg", "V/deg"): r"\degree\tothe{2}\volt\tothe{-1}",
                     ("deg/s/h", "deg/s"): r"\hour\tothe{-1}"}


def budget_results(results: etree._Element, sites: Sequence[BudgetSite]) -> None:
    """One dcc:result per budget `sites` lists (bench.report.budget_codec's of result.json)."""
    if not sites:
        return
    mr = el(results, "measurementResult", id="uncertaintyBudgets")
    name(mr, "Uncertainty budgets (EA-4/02), as the PDF's annex prints them")
    rs = el(mr, "results")
    for n, (where, owner, b) in enumerate(sites, start=1):
        unit = UNITS.get(b.unit)
        if unit is None:
            continue
        bid = ident("budget", n)
        r = el(rs, "result", id=bid, ref_type=V.BUDGET)
        name(r, f"{b.quantity}, {where}")
        text_el(r, "description", f"result.json {owner}.budgets: {b.key}" + (
            f"; {b.note}" if b.note else ""))
        data = el(r, "data")
        for i, t in enumerate(b.terms, start=1):
            tunit = UNITS.get(t.unit)
            lst = el(data, "list", id=ident(bid, "term", i))
            name(lst, f"{t.quantity}; distribution: {t.distribution}; degrees of freedom: "
                      f"{'infinite' if t.dof is None else f'{t.dof:g}'}")
            if t.estimate is not None and tunit is not None:
                quantity(lst, ident(bid, i, "x"), "estimate x_i", V.MEASURED, t.estimate, tunit)
            if tunit is not None:
                quantity(lst, ident(bid, i, "u"), "standard uncertainty u(x_i)", V.STANDARD_UNCERTAINTY,
                         t.ustd, tunit)
            cunit = SENSITIVITY_UNITS.get((b.unit, t.unit))
            if cunit is not None:
                quantity(lst, ident(bid, i, "c"), "sensitivity coefficient c_i", V.SENSITIVITY,
                         t.sensitivity, cunit)
            quantity(lst, ident(bid, i, "ui"), "contribution u_i(y)", V.STANDARD_UNCERTAINTY,
                     t.contribution, unit)
        for m, (i, j, r) in enumerate(b.correlations, start=1):
            # r enters u_c (GUM 5.2.2, docs/method.md D1)
            corr = el(data, "list", id=ident(bid, "corr", m))
            name(corr, f"correlation of inputs {i + 1} and {j + 1} ({b.terms[i].quantity}; "
                       f"{b.terms[j].quantity}): u_c^2 gains 2 r c_i u(x_i) c_j u(x_j) "
                       "(GUM 5.2.2)")
            quantity(corr, ident(bid, "corr", m, "r"), "correlation coefficient r",
                     V.CORRELATION, r, ONE)
        total = el(data, "list", id=ident(bid, "combined"))
        nu = b.dof_eff
        name(total, f"combined: effective degrees of freedom "
                    f"{'infinite' if nu is None or nu > DOF_INFINITE else f'{nu:.1f}'}; coverage "
                    f"factor {b.k:.2f} (t_95.45 of nu_eff, docs/method.md D1)"
                    + ("" if b.reported_U is None else
                       "; reproduces the U reported with the result" if b.reproduces else
                       "; does NOT reproduce the U reported with the result"))
        quantity(total, ident(bid, "uc"), "combined standard uncertainty u_c(y)", V.STANDARD_UNCERTAINTY,
                 b.ustd, unit)
        quantity(total, ident(bid, "U"), "expanded uncertainty U = k u_c", V.UNCERTAINTY, b.U, unit,
                 k=b.k)
