"""docs/method.md A3 on hand-built half means (exact arithmetic, no simulation)."""

from __future__ import annotations

import math

import pytest

from bench.analysis.crosscal import DriftEstimate, HalfMean, cross_calibrate

K, W0 = 1.0003, 0.002


def half(sign: int, t: float, w: float = 50.0, u_f: float = 1e-4, d: float = 0.0,
         u_c: float = 0.0) -> HalfMean:
    c = sign * w
    return HalfMean(sign=sign, fog_mean_dps=K * c + W0 + d * t, fog_mean_u_dps=u_f,
                    counter_mean_dps=c, counter_mean_u_dps=u_c, t_centre_s=t, turns=5)


def test_eq5_eq6_two_points():
    # F+ = 1.0003 * 50 + 0.002 = 50.017, F- = -50.013: k = 100.030 / 100, w0 = 50.017 - k 50
    cal = cross_calibrate([half(1, 0.0), half(-1, 100.0)])
    assert cal.method == "eq5-6"
    assert cal.k == pytest.approx((50.017 + 50.013) / 100.0, abs=1e-13)
    assert cal.w0_dps == pytest.approx(50.017 - cal.k * 50.0, abs=1e-12)
    assert cal.w0_dps == pytest.approx(W0, abs=1e-12)
    # u(k) = sqrt(u+^2 + u-^2) / (C+ - C-); u(w0) = sqrt((C- u+)^2 + (C+ u-)^2) / (C+ - C-)
    assert cal.k_u == pytest.approx(2 * math.sqrt(2) * 1e-4 / 100.0, rel=1e-9)
    assert cal.w0_u_dps == pytest.approx(2 * math.sqrt(2) * 50 * 1e-4 / 100.0, rel=1e-9)
    assert cal.t_ref_s == pytest.approx(50.0)


def test_counter_and_timebase_terms():
    cal = cross_calibrate([half(1, 0.0, u_f=1e-12, u_c=1e-6), half(-1, 10.0, u_f=1e-12,
                                                                      u_c=1e-6)],
                          timebase_u_rel=1e-7)
    u_k = math.hypot(K * math.sqrt(2) * 1e-6 / 100.0, K * 1e-7)
    assert cal.k_u == pytest.approx(2 * u_k, rel=1e-6)


def test_two_halves_drift_leaks_into_k_and_the_correction_removes_it():
    d = 0.001 / 3600          # 0.001 deg/s per hour
    hs = [half(1, 9000.0, w=0.1, d=d), half(-1, 27000.0, w=0.1, d=d)]
    raw = cross_calibrate(hs)
    # eq. 5 as printed: k moves by d (t+ - t-) / (W+ - W-)
    assert raw.k - K == pytest.approx(d * (9000.0 - 27000.0) / 0.2, rel=1e-9)
    # eq. 6 is the bias at the mid-time, drift or not
    assert raw.t_ref_s == pytest.approx(18000.0)
    assert raw.w0_dps == pytest.approx(W0 + d * 18000.0, abs=1e-12)
    fixed = cross_calibrate(hs, drift=DriftEstimate(d, 0.1 * d, "test"))
    assert fixed.method == "eq5-6, drift-corrected"
    assert fixed.k == pytest.approx(K, abs=1e-12)
    assert fixed.k_eq5 == pytest.approx(raw.k)
    # the drift estimate's uncertainty enters k's
    leak = 0.1 * d * 18000.0 / 0.2
    assert fixed.k_u == pytest.approx(2 * math.hypot(raw.k_u / 2, leak), rel=1e-9)


def test_three_halves_cancel_linear_drift():
    d = 0.001 / 3600
    hs = [half(1, 9000.0, w=0.1, d=d), half(-1, 27000.0, w=0.1, d=d),
          half(1, 45000.0, w=0.1, d=d)]
    cal = cross_calibrate(hs)
    assert cal.method == "lsq-drift"
    assert cal.k == pytest.approx(K, abs=1e-10)
    assert cal.drift_dps_per_s == pytest.approx(d, rel=1e-8)
    assert cal.w0_dps == pytest.approx(W0 + d * cal.t_ref_s, abs=1e-12)
    # equal weights: t_ref is the mean time
    assert cal.t_ref_s == pytest.approx(27000.0)
    # k from + - + by hand: ((F1 + F3) / 2 - F2) / (2 W); u = sqrt(u^2 / 2 + u^2) / (2 W)
    assert cal.k_u == pytest.approx(2 * math.sqrt(1.5) * 1e-4 / 0.2, rel=1e-6)


def test_needs_both_signs():
    with pytest.raises(ValueError, match="both signs"):
        cross_calibrate([half(1, 0.0), half(1, 10.0)])
