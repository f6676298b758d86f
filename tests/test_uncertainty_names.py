"""result.json's one naming rule for uncertainties: `_U` expanded (k = 2), `_ustd` standard.

The truth is where each number comes from: the analysis multiplies by k = 2 for U
(`rate_error_u_rel`, `k_u`, a harmonic's `amplitude_u_rel`) and keeps the budget's terms
standard (their root sum of squares times 2 is U).
"""

from __future__ import annotations

import math

import numpy as np

from bench.analysis.turns import CounterBudget, analyze_turns
from bench.report.uncertainty_names import explicit_name, with_explicit_names
from procedures.rate_ladder.result import turns_json


def test_names() -> None:
    assert explicit_name("rate_error_u_rel", standard=False) == "rate_error_U_rel"
    assert explicit_name("k_u", standard=False) == "k_U"
    assert explicit_name("timing_u_rel", standard=True) == "timing_ustd_rel"
    assert explicit_name("u_rel", standard=False) == "U_rel"
    assert explicit_name("rate_error_rel", standard=False) is None


def test_every_u_key_gets_its_explicit_twin_with_the_same_value() -> None:
    edges = 5.0 + np.arange(6) * 36.0 + np.array([0, 2e-7, -1e-7, 3e-7, 0, 1e-7])
    d = turns_json(analyze_turns([edges], 10.0, CounterBudget(2e-11, 2.7e-8, 1e-9)))
    out = with_explicit_names({"axes": {"outer": {"rates": [d]}},
                               "checks": [{"u_rel": 1e-7}]})
    r = out["axes"]["outer"]["rates"][0]
    b = r["rate_error_budget"]
    # U = k sqrt(sum of the budget's standard terms^2), k = t_95.45(nu_eff) as the budget
    # states it (docs/method.md D1): the _U and _ustd names say which
    total = math.sqrt(b["timing_ustd_rel"] ** 2 + b["timebase_ustd_rel"] ** 2
                      + b["repeatability_ustd_rel"] ** 2)
    assert math.isclose(r["rate_error_U_rel"], b["coverage_factor"] * total, rel_tol=1e-12)
    assert r["rate_error_U_rel"] == r["rate_error_u_rel"]      # CONTRACT key kept
    assert "timing_U_rel" not in b and "rate_error_ustd_rel" not in r
    assert out["checks"][0]["U_rel"] == 1e-7
