"""Allan deviation and the white-noise floor (docs/method.md A5) against hand values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.analysis.allan import allan_deviation, white_noise


def test_white_noise_by_hand():
    # successive differences +-1: sqrt(mean(1) / 2)
    sigma, pairs = white_noise(np.array([5.0, 6.0, 5.0, 6.0, 5.0]))
    assert sigma == pytest.approx(math.sqrt(0.5))
    assert pairs == 4


def test_white_noise_ignores_bias_and_drift():
    rng = np.random.default_rng(1)
    t = np.arange(200_000) / 1000.0
    y = 0.01 * rng.standard_normal(t.size) + 0.002 + 1e-3 / 3600 * t + 0.004  # Earth rate
    sigma, _ = white_noise(y)
    assert sigma == pytest.approx(0.01, rel=0.01)


def test_allan_deviation_of_white_noise_falls_as_sqrt_tau():
    rng = np.random.default_rng(2)
    y = 0.01 * rng.standard_normal(1 << 18)
    c = allan_deviation(y, 1000.0, m=np.array([1, 4, 64]))
    assert c.tau_s == pytest.approx((0.001, 0.004, 0.064))
    for tau, adev in zip(c.tau_s, c.adev, strict=True):
        assert adev == pytest.approx(0.01 / math.sqrt(tau * 1000.0), rel=0.05)
    assert c.terms[0] == y.size - 1


def test_allan_deviation_of_a_ramp_is_the_ramp():
    # a rate ramp r t: ADEV(tau) = r tau / sqrt(2)
    r = 1e-3
    y = r * np.arange(10_000) / 100.0
    c = allan_deviation(y, 100.0, m=np.array([10, 100]))
    for tau, adev in zip(c.tau_s, c.adev, strict=True):
        assert adev == pytest.approx(r * tau / math.sqrt(2), rel=1e-6)
