"""Uncertainty budgets as result.json holds them -> `Budget` (bench.report.budget), for the
certificate's annex and the DCC.

Why a codec of its own: a kind's result model carries its budgets (`BudgetRecord`, decoded
with the model), but the certificate and the DCC print every budget of any kind's
result.json, wherever it sits (a `budgets` list under an axis, a rate, a pair...), and name
where it sits; so the whole document is walked here, the one place its JSON is read for
budgets (or, for a result its analysis has just given, its model: `BudgetRecord`s). A budget that is not one (a term without its u, a correlation naming a term
outside the budget) is left out, not printed half: the others still are.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from bench.report.budget import Budget, BudgetRecord, Term, num
from bench.report.result_frame import Node, entries

#: (where, in a reader's words; the result.json path of the budgets' owner; the budget)
BudgetSite = tuple[str, str, Budget]


def budget_from_json(d: Mapping[str, Any]) -> Budget | None:
    """A budget as result.json carries it (None when it is not one)."""
    try:
        terms = tuple(Term(str(t["quantity"]), num(t.get("estimate")), float(t["ustd"]),
                           str(t["distribution"]), float(t["sensitivity"]),
                           num(t.get("dof")), str(t.get("unit") or ""))
                      for t in d["terms"])
        corr = tuple((int(c["terms"][0]), int(c["terms"][1]), float(c["r"]))
                     for c in d.get("correlations") or ())
        if any(not (0 <= i < len(terms) and 0 <= j < len(terms)) for i, j, _ in corr):
            return None
        return Budget(str(d["quantity"]), str(d["key"]), str(d.get("unit") or ""),
                      num(d.get("estimate")), terms, num(d.get("U_reported")),
                      str(d.get("note") or ""), corr)
    except (KeyError, TypeError, ValueError, IndexError):
        return None


def _site(path: tuple[str | int, ...], node: Node) -> str:
    """Where a budget belongs, for a reader: 'axis outer, +10 deg/s', 'axis x', ..."""
    axis = next((str(path[i + 1]) for i in range(len(path) - 1)
                 if path[i] == "axes"), None)
    where = [f"axis {axis}"] if axis else []
    stated = dict(entries(node))
    if (rate := num(stated.get("set_rate_dps"))) is not None:
        where.append(f"{rate:+g} °/s")
    elif (pair := num(stated.get("rate_dps"))) is not None:
        where.append(f"pair ±{pair:g} °/s")
    return ", ".join(where) or "overall"


def budget_sites(node: Node, path: tuple[str | int, ...] = ()) -> list[BudgetSite]:
    """(where, result.json path of the owner, budget) for every budget under `node`, in
    document order."""
    out: list[BudgetSite] = []
    for k, v in entries(node):
        if k == "budgets" and isinstance(v, list | tuple):
            owner = ".".join(str(p) if not isinstance(p, int) else f"[{p}]"
                             for p in path).replace(".[", "[")
            for d in v:
                b = d.budget() if isinstance(d, BudgetRecord) else \
                    budget_from_json(d) if isinstance(d, dict) else None
                if b is not None:
                    out.append((_site(path, node), owner, b))
        else:
            out += budget_sites(v, (*path, k))
    return out
