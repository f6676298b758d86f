"""result.json's one naming rule for uncertainties: `_U` expanded (k = 2), `_ustd` standard.

The truth is where each number comes from: the analysis multiplies by k for U
(`rate_error_u_rel`) and keeps the budget's terms standard (their root sum of squares
times k is U). The rate ladder's result model (procedures/rate_ladder/result.py) writes
each twin as a field of its own, so no key is derived by a rule over names (issue 60).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.analysis.turns import CounterBudget, analyze_turns
from bench.report.codec import encode
from bench.report.result_frame import MalformedResult
from procedures.rate_ladder.codec import ladder_of
from procedures.rate_ladder.result import RateEntry, rate_error_budget


def _turns() -> RateEntry:
    edges = 5.0 + np.arange(6) * 36.0 + np.array([0, 2e-7, -1e-7, 3e-7, 0, 1e-7])
    tr = analyze_turns([edges], 10.0, CounterBudget(2e-11, 2.7e-8, 1e-9))
    return RateEntry(set_rate_dps=tr.set_rate_dps, turns=tr.turns,
                     rate_error_rel=tr.rate_error_rel, rate_error_u_rel=tr.rate_error_u_rel,
                     rate_error_U_rel=tr.rate_error_u_rel, rate_error_budget=rate_error_budget(tr))


def test_every_u_key_has_its_explicit_twin_with_the_same_value() -> None:
    r = _turns()
    b = r.rate_error_budget
    assert b is not None and b.timing_ustd_rel is not None
    assert b.timebase_ustd_rel is not None and b.repeatability_ustd_rel is not None
    assert b.coverage_factor is not None and r.rate_error_U_rel is not None
    # U = k sqrt(sum of the budget's standard terms^2), k = t_95.45(nu_eff) as the budget
    # states it (docs/method.md D1): the _U and _ustd names say which
    total = math.sqrt(b.timing_ustd_rel ** 2 + b.timebase_ustd_rel ** 2
                      + b.repeatability_ustd_rel ** 2)
    assert math.isclose(r.rate_error_U_rel, b.coverage_factor * total, rel_tol=1e-12)
    doc = encode(r)
    keys = list(doc)
    # the CONTRACT key kept, its twin beside it; a budget's terms are standard, never _U
    assert keys[keys.index("rate_error_u_rel") + 1] == "rate_error_U_rel"
    assert doc["rate_error_U_rel"] == doc["rate_error_u_rel"]
    budget = doc["rate_error_budget"]
    assert isinstance(budget, dict)
    assert budget["timing_ustd_rel"] == budget["timing_u_rel"]
    assert "timing_U_rel" not in budget and "rate_error_ustd_rel" not in doc


def _result(rate: dict[str, object]) -> dict[str, object]:
    return {"schema": "bench.result/1", "procedure": "rate-ladder",
            "axes": {"outer": {"rates": [rate], "pairs": []}}}


def test_twins_that_differ_are_refused_and_an_older_result_reads_its_u_key() -> None:
    with pytest.raises(MalformedResult, match=r"axes\.outer\.rates\[0\] `rate_error_U_rel` "
                                              r"2e-07 differs from `rate_error_u_rel` 1e-07"):
        ladder_of(_result({"set_rate_dps": 10.0, "rate_error_u_rel": 1e-7,
                           "rate_error_U_rel": 2e-7}))
    older = ladder_of(_result({"set_rate_dps": 10.0, "rate_error_u_rel": 1e-7}))
    assert older.axes["outer"].rates[0].rate_error_U_rel == 1e-7
