"""Settling judged on transients, the turn's steady ripple set aside (issue 41).

Known truth: synthetic drive readings with the seed paper's outer-axis ripple (8.6e-4 of
the rate once per turn, 1.5e-4 twice per turn: the shipped two-axis stand's truth) at
-50 deg/s, where the ripple's peak (0.0505 deg/s) is above a 1e-3 relative tolerance
(0.05 deg/s); then the same run on the twins of configs/stands/sim-two-axis.yaml.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from drivers.settle import MIN_TURNS, hold_spans_turns, judge_with_ripple
from tests.conftest import CONFIGS, bench

RATE_DPS = -50.0
TOL_DPS = 1e-3 * abs(RATE_DPS)
TPDO_HZ = 100.0


def readings(hold_s: float = 20.0, noise_dps: float = 1e-4, seed: int = 3
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, velocity, position) of a table at RATE_DPS with the stand's ripple."""
    t = np.arange(0.0, hold_s, 1.0 / TPDO_HZ)
    pos = 123.0 + RATE_DPS * t
    phi = np.deg2rad(pos)
    v = RATE_DPS * (1 + 8.6e-4 * np.cos(phi + np.deg2rad(40))
                    + 1.5e-4 * np.cos(2 * phi - np.deg2rad(70)))
    v = v + np.random.default_rng(seed).normal(0.0, noise_dps, t.size)
    return t, v, pos


def test_the_steady_ripple_is_set_aside_and_stated() -> None:
    t, v, pos = readings()
    assert np.max(np.abs(v - RATE_DPS)) > TOL_DPS        # reading by reading: never settles
    j = judge_with_ripple(t, v, pos, RATE_DPS, TOL_DPS)
    assert j is not None and j.settled
    assert j.ripple_peak_dps == pytest.approx(50 * (8.6e-4 + 1.5e-4), rel=0.1)
    assert j.mean_dps == pytest.approx(RATE_DPS, abs=1e-4)
    assert j.turns == pytest.approx((t[-1] - t[0]) * 50 / 360)
    assert j.worst_residual_dps < 10 * 1e-4


@pytest.mark.parametrize("step_s, size", [(12.0, 1.0), (5.0, 1.0), (18.0, 1.2)])
def test_a_velocity_step_the_size_of_the_tolerance_holds_the_settle_back(
        step_s: float, size: float) -> None:
    t, v, pos = readings()
    v = v + np.where(t >= step_s, size * TOL_DPS, 0.0)      # the rate moves by a tolerance
    j = judge_with_ripple(t, v, pos, RATE_DPS, TOL_DPS)
    assert j is not None and not j.settled, j
    assert j.last_out is not None and t[j.last_out] >= step_s


def test_a_short_transient_holds_it_back_too() -> None:
    t, v, pos = readings()
    v = v + np.where((t >= 9.0) & (t < 10.0), 1.5 * TOL_DPS, 0.0)
    j = judge_with_ripple(t, v, pos, RATE_DPS, TOL_DPS)
    assert j is not None and not j.settled


def test_a_hold_shorter_than_two_turns_is_judged_reading_by_reading() -> None:
    t, v, pos = readings(hold_s=0.99 * MIN_TURNS * 360 / abs(RATE_DPS))
    assert judge_with_ripple(t, v, pos, RATE_DPS, TOL_DPS) is None
    assert not hold_spans_turns(2.0, 10.0) and hold_spans_turns(20.0, -50.0)


@pytest.mark.timeout(240)
def test_minus_50_dps_with_a_1e3_tolerance_settles_on_the_two_axis_twins(
        tmp_path: Path) -> None:
    """Issue 41's case on the shipped stand's twins: tolerance_rel 1e-3, hold 20 s, -50
    deg/s. Reading by reading the ripple touched 0.0502 deg/s once a turn and the run
    aborted after timeout_s; now it settles, and says what it set aside."""
    stand = CONFIGS / "stands" / "sim-two-axis.yaml"
    proc = tmp_path / "settle.yaml"
    proc.write_text(f"procedure: rate-ladder\ntitle: settle on a rippling axis\n"
                    f"stand: {stand}\nturns: 2\nstatic_record_s: 2\nprompts: false\n"
                    "settle: {tolerance_rel: 1.0e-3, tolerance_dps: 0.001, hold_s: 20, "
                    "timeout_s: 60}\naxes:\n  outer:\n    rates_dps: [50]\n")
    out = bench("run", str(proc), "--yes", "--out", str(tmp_path / "runs"), timeout=230)
    assert out.returncode in (0, 1), out.stderr[-3000:]
    assert "did not settle" not in out.stderr
    assert "a steady ripple of the turn" in out.stderr, out.stderr[:3000]
