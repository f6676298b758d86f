"""The gyro-platform twin against hand-derived truth (docs/method.md B)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from procedures.drift_pulse.analysis import EARTH_RATE_DPH
from sims.clock import VirtualClock
from sims.platform import GyroPlatform, GyroTruth, PlatformTruth
from sims.stand import AxisTruth, SimulatedStand, StandTruth

K_AS = 2.0          # V/deg
KC = 0.1            # deg/s per V


def quiet(**kw: float) -> GyroTruth:
    base = dict(own_drift_dph=0.35, precession_dps_per_v=KC, k_as_v_per_deg=K_AS,
                angle_offset_deg=0.25)
    base.update(kw)
    return GyroTruth(**base)


def platform(gyros: dict[str, GyroTruth], azimuth: float = 80.0, grid_hz: float = 100.0,
             **kw) -> GyroPlatform:
    return GyroPlatform(PlatformTruth(70.0, azimuth, gyros, **kw), grid_hz=grid_hz)


def test_apparent_drift_follows_the_convention() -> None:
    truth = PlatformTruth(70.0, 80.0, {"x": quiet(), "y": quiet(), "z": quiet()})
    wh = 15.041 * math.cos(math.radians(70.0))
    assert truth.apparent_dph("x") == pytest.approx(wh * math.cos(math.radians(80.0)))
    assert truth.apparent_dph("y") == pytest.approx(-wh * math.sin(math.radians(80.0)))
    assert truth.apparent_dph("z") == pytest.approx(15.041 * math.sin(math.radians(70.0)))
    # a 180 deg turn about the vertical flips the horizontal ones only
    assert truth.apparent_dph("x", 180.0) == pytest.approx(-truth.apparent_dph("x"))
    assert truth.apparent_dph("y", 180.0) == pytest.approx(-truth.apparent_dph("y"))
    assert truth.apparent_dph("z", 180.0) == pytest.approx(truth.apparent_dph("z"))
    assert EARTH_RATE_DPH == 15.041


def test_angle_sensor_reads_the_drift_ramp() -> None:
    p = platform({"x": quiet()})
    t = np.array([0.0, 10.0, 100.0, 1000.5])
    u = p.sample_u("x", t)
    w_dps = (0.35 + 15.041 * math.cos(math.radians(70)) * math.cos(math.radians(80))) / 3600
    np.testing.assert_allclose(u, K_AS * (0.25 + w_dps * t), rtol=0, atol=1e-12)


def test_rectangular_pair_precesses_out_and_back() -> None:
    p = platform({"x": quiet(own_drift_dph=0.0)}, azimuth=90.0)  # app_x = 0
    tc, dt, amp_v = 5.0, 1e-3, 2.0
    volts = np.concatenate((np.full(5000, amp_v), np.full(5000, -amp_v)))
    p.apply_voltage("x", 1.0, dt, volts)
    u = p.sample_u("x", np.array([0.5, 1.0, 1.0 + tc / 2, 1.0 + tc, 1.0 + 1.5 * tc,
                                  1.0 + 2 * tc, 20.0]))
    a = KC * amp_v  # deg/s
    expect = K_AS * (0.25 + np.array([0, 0, a * tc / 2, a * tc, a * tc / 2, 0, 0]))
    np.testing.assert_allclose(u, expect, atol=1e-12)


def test_mismatch_leaves_a_net_angle_and_aperture_averages() -> None:
    eps = 1e-3
    p = platform({"x": quiet(own_drift_dph=0.0, pulse_mismatch_rel=eps)}, azimuth=90.0)
    volts = np.concatenate((np.ones(100), -np.ones(100)))
    p.apply_voltage("x", 0.0, 0.01, volts)
    # after the pair: -eps * a * Tc of angle remains
    assert p.sample_u("x", 3.0)[0] == pytest.approx(K_AS * (0.25 - eps * KC * 1.0), abs=1e-12)
    # an integrating reading is the mean over its aperture: check against fine point samples
    q = platform({"x": quiet(own_drift_dph=0.0)}, azimuth=90.0)
    q.apply_voltage("x", 0.0, 0.01, volts)
    ap = 0.004
    t = np.array([0.998, 1.5])  # across the +/- edge, and inside the second pulse
    fine = [q.sample_u("x", ti + (np.arange(4000) + 0.5) * ap / 4000).mean() for ti in t]
    r = platform({"x": quiet(own_drift_dph=0.0)}, azimuth=90.0)
    r.apply_voltage("x", 0.0, 0.01, volts)
    np.testing.assert_allclose(r.sample_u("x", t, aperture_s=ap), fine, atol=1e-9)


def test_pulse_edges_jitter_with_the_stated_std() -> None:
    sigma = 20e-6
    p = platform({"x": quiet(own_drift_dph=0.0, pulse_jitter_s=sigma)}, azimuth=90.0,
                 grid_hz=10.0)
    left = []
    for k in range(400):
        t0 = 10.0 * k
        p.apply_voltage("x", t0, 1.0, np.array([1.0, -1.0]))
        left.append(p.sample_u("x", t0 + 3.0)[0] / K_AS - 0.25)
    # edges at j0, 1 + j1, 2 + j2 leave a * (2 j1 - j0 - j2) per pair: std a sqrt(6) sigma
    net = np.diff(np.concatenate(([0.0], left))) / KC
    assert np.std(net) == pytest.approx(math.sqrt(6) * sigma, rel=0.15)
    assert abs(np.mean(net)) < 3 * math.sqrt(6) * sigma / math.sqrt(400)


def test_random_walk_has_the_stated_strength_and_seeds_repeat() -> None:
    q = 0.5  # deg/h per sqrt(h), large to measure in a short test
    gyros = {g: quiet(drift_random_walk_dph_per_rth=q, angle_noise_arcsec=1.0) for g in "xy"}
    p1, p2 = platform(gyros, seed=7, grid_hz=1.0), platform(gyros, seed=7, grid_hz=1.0)
    t = np.linspace(0.0, 3600.0, 50)
    np.testing.assert_array_equal(p1.sample_u("x", t), p2.sample_u("x", t))
    hours = np.arange(0.0, 100.0, 0.1)
    own = np.array([p1.own_drift_dph("x", h * 3600.0, h * 3600.0) for h in hours])
    assert own[0] == 0.35
    assert np.std(np.diff(own)) == pytest.approx(q * math.sqrt(0.1), rel=0.15)


def test_turntable_turn_flips_the_apparent_drift() -> None:
    clock = VirtualClock(1.0, running=False)
    stand = SimulatedStand(StandTruth(1, {"turntable": AxisTruth()}), {"turntable": 100.0},
                           clock)
    truth = PlatformTruth(70.0, 80.0, {"x": quiet(), "y": quiet(own_drift_dph=-0.42)},
                          table_axis="turntable", seed=1)
    p = GyroPlatform(truth, stand)
    table = stand.axis("turntable")
    # 180 deg: 1 s ramp to 30 deg/s, 5 s cruise, 1 s ramp down (15 + 150 + 15 deg)
    table.command_rate(100.0, 30.0, 30.0)
    table.profile.command(106.0, 0.0, 30.0)
    for g in "xy":
        before = np.diff(p.sample_u(g, np.array([0.0, 90.0])))[0] / (K_AS * 90.0) * 3600
        after = np.diff(p.sample_u(g, np.array([120.0, 300.0])))[0] / (K_AS * 180.0) * 3600
        own = truth.gyros[g].own_drift_dph
        assert before == pytest.approx(own + truth.apparent_dph(g, 0.0), abs=1e-9)
        assert after == pytest.approx(own + truth.apparent_dph(g, 180.0), abs=1e-6)
    assert p.table_deg == pytest.approx(180.0, abs=1e-6)
    assert p.heading_deg == pytest.approx(260.0, abs=1e-6)


def test_a_pulse_before_what_was_read_is_refused() -> None:
    p = platform({"x": quiet()})
    p.sample_u("x", 5.0)
    with pytest.raises(RuntimeError, match="causality"):
        p.apply_voltage("x", 4.0, 0.1, np.ones(3))
