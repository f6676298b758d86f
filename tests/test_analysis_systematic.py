"""docs/method.md A4: angle of each sample, binned estimator and harmonic fit against truth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.analysis import CounterBudget, FogCalibration, Window, analyze_pair
from bench.analysis.angle import sample_angles_deg
from sims.stand import AxisTruth, FogTruth, Harmonic
from tests.test_analysis_sim import paper_axis, simulate_pair

A, P = 1e-3, 40.0


def pure_harmonic_axis() -> AxisTruth:
    """One harmonic in angle and nothing else but a whisper of FOG noise."""
    return AxisTruth(harmonics=(Harmonic(1, A, P),),
                     fog=FogTruth(scale=1.0003, bias_dps=0.002, noise_dps=1e-9))


@pytest.fixture(scope="module")
def pure() -> tuple:
    sp = simulate_pair(pure_harmonic_axis(), 50.0, 3, order="+-", seed=5)
    res = analyze_pair(sp.halves, 50.0, fog_rate_hz=1000.0, mains_hz=None, harmonics=3,
                       binned_deg=10.0)
    return sp, res


def test_angles_follow_the_stand():
    sp = simulate_pair(paper_axis(), 50.0, 3, order="+-", seed=6, keep_truth=True)
    fog = sp.truth.fog
    for i, h in enumerate(sp.halves):
        win = Window.from_record(h, i)
        truth = np.mod(sp.phi_deg[win.s_lo:win.s_hi], 360.0)
        for cal in (FogCalibration(fog.k, fog.bias_dps, fog.bias_drift_dps_per_h / 3600),
                    FogCalibration(1.0, 0.0)):   # k cancels; a bias of 4e-5 w barely counts
            phi = sample_angles_deg(win, cal)
            err = (phi - truth + 180.0) % 360.0 - 180.0
            assert np.max(np.abs(err)) < 0.01, (i, cal)
        # the angle falls through a negative turn
        if h.sign < 0:
            assert np.median(np.diff(phi)) < 0


def test_binned_estimator_on_a_pure_harmonic(pure):
    sp, res = pure
    for r in res.rates:
        b = r.systematic.binned
        phi = np.radians(np.array(b.centres_deg))
        half = math.radians(b.bin_deg) / 2
        # docs/method.md A4: the mean over a bin of a cos(phi + p) is a cos(phi_c + p) sinc(half)
        expect = A * math.sin(half) / half * np.cos(phi + math.radians(P))
        assert np.allclose(b.deviation_rel, expect, atol=2e-6), r.set_rate_dps
        assert b.peak_to_peak_rel == pytest.approx(2 * A, rel=0.02)


def test_harmonic_fit_recovers_a_pure_harmonic(pure):
    _, res = pure
    for r in res.rates:
        h1, h2, h3 = r.systematic.harmonics
        assert h1.amplitude_rel == pytest.approx(A, rel=1e-3)
        assert h1.phase_deg == pytest.approx(P, abs=0.05)
        assert h2.amplitude_rel < 1e-6 and h3.amplitude_rel < 1e-6
    assert res.pair.k == pytest.approx(pure_harmonic_axis().fog.k, abs=1e-8)


def test_several_harmonics_are_separated_exactly():
    # near noise-free: the fit must be exact to far below any uncertainty it reports
    truth = AxisTruth(harmonics=(Harmonic(1, 3e-4, -20.0), Harmonic(3, 2e-4, 110.0)),
                      fog=FogTruth(noise_dps=1e-6))
    sp = simulate_pair(truth, 100.0, 4, order="+-", seed=8)
    res = analyze_pair(sp.halves, 100.0, fog_rate_hz=1000.0, mains_hz=None,
                       counter_budget=CounterBudget())
    for r in res.rates:
        h = {x.order: x for x in r.systematic.harmonics}
        for order, amp, ph in ((1, 3e-4, -20.0), (3, 2e-4, 110.0)):
            assert h[order].amplitude_rel == pytest.approx(amp, abs=1e-9)
            assert h[order].phase_deg == pytest.approx(ph, abs=1e-3)
        assert h[2].amplitude_rel < 1e-9 and h[4].amplitude_rel < 1e-9
