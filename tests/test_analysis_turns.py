"""docs/method.md A1/A2 against hand-derived values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.analysis.turns import (
    CounterBudget,
    analyze_turns,
    edges_from_periods,
    period_rate_error,
    turn_rates_dps,
)
from procedures.rate_ladder.result import turns_entry


def test_a1_check_value():
    # docs/method.md A1: dT = 0.1 us at 1000 deg/s (T = 0.36 s) gives dw/w = 2.8e-7
    rel = period_rate_error(1000.0, 0.1e-6, 0.36) / 1000.0
    assert rel == pytest.approx(2.8e-7, rel=0.01)
    assert rel == pytest.approx(0.1e-6 / (0.36 + 0.1e-6), rel=1e-12)


def test_budget_per_period_is_two_edges():
    b = CounterBudget(timestamp_u_s=20e-9, trigger_jitter_s=27e-9, timebase_limit_rel=1e-7)
    edge = math.hypot(20e-9, 27e-9)
    assert b.edge_u_s == pytest.approx(edge)
    assert b.period_u_s == pytest.approx(math.sqrt(2) * edge)
    assert b.timebase_u_rel == pytest.approx(1e-7 / math.sqrt(3))
    with pytest.raises(ValueError, match="trigger_jitter_s"):
        CounterBudget(trigger_jitter_s=-1.0)


def test_rates_signed_by_the_command():
    e = np.array([0.0, 7.2, 14.4])
    assert np.allclose(turn_rates_dps(e, -1), [-50.0, -50.0])


def test_rate_error_instability_and_u_by_hand():
    # two windows at -50 deg/s: periods 7.2 s * (1 + e_i)
    e1 = edges_from_periods(10.0, 7.2 * np.array([1 + 1e-6, 1 - 1e-6, 1 + 2e-6]))
    e2 = edges_from_periods(100.0, 7.2 * np.array([1.0, 1 + 3e-6]))
    b = CounterBudget(trigger_jitter_s=27e-9, timebase_limit_rel=2e-8)
    r = analyze_turns([e1, e2], -50.0, b)
    periods = 7.2 * np.array([1 + 1e-6, 1 - 1e-6, 1 + 2e-6, 1.0, 1 + 3e-6])
    rates = -360.0 / periods
    mean = -360.0 * 5 / periods.sum()           # angle / time, not the mean of the rates
    assert r.turns == 5
    assert np.allclose(r.counter_rate_dps, rates, rtol=1e-14)
    assert r.mean_rate_dps == pytest.approx(mean, rel=1e-14)
    assert r.rate_error_rel == pytest.approx((mean + 50.0) / -50.0, abs=1e-13)
    # eq. 2 with the square root: relative standard deviation
    assert r.rate_instability_rel == pytest.approx(
        np.sqrt(np.sum((rates - rates.mean()) ** 2) / 4) / abs(rates.mean()), rel=1e-9)
    # U: each window's two end edges, the timebase (rectangular) and the turn-to-turn
    # repeatability (eq. 2 / sqrt(N), N - 1 = 4 dof); k = t_95.45(nu_eff) by
    # Welch-Satterthwaite (docs/method.md D1), by hand with scipy's t
    from scipy.stats import norm, t

    timing = math.sqrt(2 * 2) * 27e-9 / periods.sum()
    repeat = r.rate_instability_rel / math.sqrt(5)
    u = math.sqrt(timing ** 2 + (2e-8 / math.sqrt(3)) ** 2 + repeat ** 2)
    nu_eff = u ** 4 / (repeat ** 4 / 4)
    k = round(float(t.ppf(norm.cdf(2), math.floor(nu_eff))), 2)
    assert r.dof_eff == pytest.approx(nu_eff, rel=1e-9)
    assert r.coverage_factor == k
    assert r.rate_error_u_rel == pytest.approx(k * u, rel=1e-9)
    d = turns_entry(r)   # as result.json states it
    assert d.set_rate_dps == -50.0 and d.turns == 5
    assert len(d.counter_rate_dps) == 5 and all(x is not None and x < 0
                                                 for x in d.counter_rate_dps)


def test_one_turn_has_no_instability():
    r = analyze_turns([np.array([0.0, 3.6])], 100.0, CounterBudget())
    assert r.rate_instability_rel is None
    assert r.rate_error_rel == pytest.approx(0.0, abs=1e-15)


def test_missed_zero_mark_is_named():
    e = np.array([0.0, 7.2, 21.6, 28.8])   # the mark at 14.4 s was missed
    with pytest.raises(ValueError, match="turn 1.*missed or extra zero mark"):
        analyze_turns([e], 50.0, CounterBudget())


def test_edges_must_increase():
    with pytest.raises(ValueError, match="window 0: edge times must be strictly increasing"):
        analyze_turns([np.array([0.0, 7.2, 7.2])], 50.0, CounterBudget())
