"""The simulated stand against hand-derived truth: it is the reference every twin samples."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sims.stand import (
    RNG_BLOCK_SAMPLES,
    AxisChunk,
    AxisModel,
    AxisTruth,
    FogTruth,
    Harmonic,
    Mains,
)


def _record(ax: AxisModel) -> list[AxisChunk]:
    chunks: list[AxisChunk] = []
    ax.listeners.append(chunks.append)
    return chunks


def test_an_ideal_axis_turns_exactly_at_the_commanded_rate() -> None:
    ax = AxisModel(AxisTruth(), rate_hz=1000.0, seed=1)
    ax.command_rate(0.0, 90.0, 45.0)          # 2 s ramp, 90 deg of it
    ax.advance_to(20.0)
    marks = ax.zero_marks().t_true_s
    # phi = 90 deg at t = 2 s, then 90 deg/s: marks at 2 + (360k - 90) / 90
    expected = 2.0 + (360.0 * np.arange(1, marks.size + 1) - 90.0) / 90.0
    np.testing.assert_allclose(marks, expected, atol=1e-9)
    assert ax.rate_dps == pytest.approx(90.0, abs=1e-12)


def test_the_ramp_respects_the_acceleration_and_reverses_continuously() -> None:
    ax = AxisModel(AxisTruth(), rate_hz=1000.0, seed=1)
    chunks = _record(ax)
    ax.command_rate(0.0, 100.0, 50.0)
    ax.command_rate(1.0, -100.0, 50.0)        # reverse mid-ramp, from 50 deg/s
    ax.advance_to(6.0)
    w = np.concatenate([c.rate_cmd_dps for c in chunks])
    accel = np.abs(np.diff(w)) * 1000.0
    assert accel.max() <= 50.0 + 1e-6
    assert w[1000] == pytest.approx(50.0)
    assert w[-1] == pytest.approx(-100.0)


def test_the_fog_sees_k_times_the_true_rate_plus_bias_and_drift() -> None:
    fog = FogTruth(scale=1.001, bias_dps=0.01, misalignment_deg=2.0, bias_drift_dps_per_h=3.6)
    ax = AxisModel(AxisTruth(fog=fog), rate_hz=500.0, seed=2)
    chunks = _record(ax)
    ax.command_rate(0.0, 20.0, 100.0)
    ax.advance_to(10.0)
    c = chunks[0]
    k = 1.001 * math.cos(math.radians(2.0))
    np.testing.assert_allclose(c.fog_dps, k * c.w_true_dps + 0.01 + 0.001 * c.t_s, rtol=0,
                               atol=1e-12)


def test_harmonics_lower_the_per_turn_rate_by_half_their_square() -> None:
    truth = AxisTruth(rate_bias_rel=1e-6, harmonics=(Harmonic(1, 1e-3, 30.0),))
    # the harmonic mean of 1 + b + a cos: (1 + b) * (1 - a^2 / 2) to first order in b
    assert truth.mean_turn_rate_rel() == pytest.approx(1e-6 - 0.5e-6, abs=2e-9)
    ax = AxisModel(truth, rate_hz=1000.0, seed=3)
    ax.command_rate(0.0, 60.0, 1e6)
    ax.advance_to(60.0)
    t = ax.zero_marks().t_true_s
    w = 360.0 * (t.size - 1) / (t[-1] - t[0])
    assert w / 60.0 - 1.0 == pytest.approx(truth.mean_turn_rate_rel(), abs=2e-9)


def test_the_same_seed_gives_the_same_record_whatever_the_chunking() -> None:
    truth = AxisTruth(harmonics=(Harmonic(1, 8.6e-4, 40.0),), mains=Mains(50.0, 2e-4),
                      rate_noise_dps=1e-4, turn_jitter_s=27e-9, fog=FogTruth(noise_dps=0.01))
    a, b = AxisModel(truth, 1000.0, 7), AxisModel(truth, 1000.0, 7)
    ca, cb = _record(a), _record(b)
    for ax in (a, b):
        ax.command_rate(0.0, 50.0, 200.0)
    a.advance_to(30.0)
    for t in np.arange(0.5, 30.0, 0.77):
        b.advance_to(float(t))
    b.advance_to(30.0)
    fa = np.concatenate([c.fog_dps for c in ca])
    fb = np.concatenate([c.fog_dps for c in cb])
    # samples on a fixed block grid, noise keyed by block: bit for bit (issue 27)
    assert np.array_equal(fa, fb)
    assert np.array_equal(a.zero_marks().t_edge_s, b.zero_marks().t_edge_s)
    again = AxisModel(truth, 1000.0, 7)
    cg = _record(again)
    again.command_rate(0.0, 50.0, 200.0)
    again.advance_to(30.0)
    assert np.array_equal(np.concatenate([x.fog_dps for x in cg]), fa)  # bit for bit
    c = AxisModel(truth, 1000.0, 8)
    cc = _record(c)
    c.command_rate(0.0, 50.0, 200.0)
    c.advance_to(30.0)
    assert not np.allclose(np.concatenate([x.fog_dps for x in cc]), fa)


def test_a_command_mid_block_leaves_what_was_released_and_the_rest_reproducible() -> None:
    """Where a twin's look at the stand falls (the clock's steps) never changes a number:
    a command inside a block computed earlier recomputes it; the samples released
    before come out the same, and the whole record equals one made in other steps."""
    truth = AxisTruth(harmonics=(Harmonic(1, 1e-4, 30.0), Harmonic(2, 5e-5)),
                      rate_noise_dps=1e-3, turn_jitter_s=1e-6, fog=FogTruth(noise_dps=0.01))

    def record(steps: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        ax = AxisModel(truth, 1000.0, np.random.SeedSequence(3).spawn(2)[1])
        out = _record(ax)
        ax.command_rate(0.5, 100.0, 50.0)
        reversed_ = False
        for t in steps:
            if t >= 7.3 and not reversed_:
                ax.command_rate(7.3, -50.0, 50.0)   # inside block 0 (0 .. 16.384 s)
                reversed_ = True
            ax.advance_to(float(t))
        ax.advance_to(30.0)
        return (np.concatenate([c.fog_dps for c in out]), ax.zero_marks().t_edge_s,
                ax.angle_deg)

    fine = record(np.arange(0.0, 30.0, 0.01))
    coarse = record(np.sort(np.random.default_rng(5).uniform(0.0, 30.0, 50)))
    assert fine[0].size == 30_001 and fine[1].size >= 2
    assert np.array_equal(fine[0], coarse[0])
    assert np.array_equal(fine[1], coarse[1])
    assert fine[2] == coarse[2]


def test_the_seeded_numbers_follow_the_random_number_grid_not_the_computation_blocks() -> None:
    """The stand computes in BLOCK_SAMPLES blocks for speed; its random numbers come from
    the fixed RNG_BLOCK_SAMPLES grid, so a block size that is a multiple of the grid
    changes no draw: the same FOG noise bit for bit at rest, and turning the same
    record up to the fixed point's rounding (hand bound: 1e-9 deg/s, 1e-9 s)."""
    truth = AxisTruth(harmonics=(Harmonic(1, 8.6e-4, 40.0), Harmonic(2, 1.5e-4, -70.0)),
                      mains=Mains(50.0, 2e-4), rate_noise_dps=1e-4, turn_jitter_s=27e-9,
                      fog=FogTruth(scale=1.0003, bias_dps=0.002, noise_dps=0.01))

    def record(block: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ax = AxisModel(truth, 1000.0, 7, block_samples=block)
        out = _record(ax)
        ax.advance_to(20.0)                      # at rest: bias and noise alone
        ax.command_rate(20.0, 90.0, 45.0)
        ax.advance_to(70.0)
        m = ax.zero_marks()
        return np.concatenate([c.fog_dps for c in out]), m.t_edge_s, m.t_edge_s - m.t_true_s

    small, large = record(RNG_BLOCK_SAMPLES), record(4 * RNG_BLOCK_SAMPLES)
    rest = slice(0, 20_001)
    assert np.array_equal(small[0][rest], large[0][rest])
    np.testing.assert_allclose(large[0], small[0], rtol=0, atol=1e-9)
    assert small[1].size == large[1].size >= 10
    np.testing.assert_allclose(large[1], small[1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(large[2], small[2], rtol=0, atol=1e-15)  # the same jitter draws
    with pytest.raises(ValueError, match="multiple of 4096"):
        AxisModel(truth, 1000.0, 7, block_samples=5000)


def test_edge_jitter_has_the_stated_spread() -> None:
    ax = AxisModel(AxisTruth(turn_jitter_s=27e-9), rate_hz=1000.0, seed=4)
    ax.command_rate(0.0, 360.0, 1e6)
    ax.advance_to(2000.0)
    m = ax.zero_marks()
    d = m.t_edge_s - m.t_true_s
    assert d.size > 1900
    assert np.std(d) == pytest.approx(27e-9, rel=0.1)


def test_a_reversal_slows_with_the_deceleration_then_speeds_up_with_the_acceleration() -> None:
    ax = AxisModel(AxisTruth(), rate_hz=1000.0, seed=1)
    chunks = _record(ax)
    ax.command_rate(0.0, 100.0, 100.0)                  # at +100 from t = 1 s
    ax.command_rate(2.0, -100.0, 50.0, decel_dps2=200.0)
    ax.advance_to(6.0)
    w = np.concatenate([c.rate_cmd_dps for c in chunks])
    # 100 -> 0 at 200 deg/s^2 takes 0.5 s; 0 -> -100 at 50 deg/s^2 takes 2 s
    assert w[2250] == pytest.approx(50.0)
    assert w[2500] == pytest.approx(0.0, abs=1e-9)
    assert w[3500] == pytest.approx(-50.0)
    assert w[4500] == pytest.approx(-100.0)


def _fixed_point_directly(truth: AxisTruth, t_s: np.ndarray, w_cmd: np.ndarray,
                          block: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The stand's solve of phi = phi_last + cumtrapz(w(phi, t)), block by block, with
    every cos taken directly (numpy's cos of the angle and of 2 pi f t): 3 passes from
    the first guess that ignores harmonics, as sims/stand.py documents."""
    m = truth.mains
    assert m is not None
    tone_all = np.where(w_cmd != 0.0, m.amplitude_dps * np.cos(
        2 * np.pi * m.frequency_hz * t_s + math.radians(m.phase_deg)), 0.0)
    w_out, phi_out = np.empty_like(t_s), np.empty_like(t_s)
    phi_last = w_last = 0.0
    for b0 in range(0, t_s.size, block):
        sl = slice(b0, b0 + block)
        wc, tone = w_cmd[sl], tone_all[sl]
        phi = phi_last + np.cumsum(wc) * dt
        for _ in range(3):
            w = wc * (1.0 + truth.shape_rel(phi)) + tone
            phi = phi_last + np.cumsum(0.5 * (np.concatenate(([w_last], w[:-1])) + w)) * dt
        if b0 == 0:
            phi -= 0.5 * (w_last + w[0]) * dt
        w_out[sl], phi_out[sl] = w, phi
        phi_last, w_last = float(phi[-1]), float(w[-1])
    return w_out, phi_out


@pytest.mark.parametrize("amplitude_rel", [8.6e-4, 2.0e-2])
def test_the_rate_is_the_truths_at_the_angle_the_stand_reports(amplitude_rel: float) -> None:
    """w = w_cmd (1 + shape_rel(phi)) + tone(t) (CONTRACT §2), solved for phi on the
    grid: the stand's shortcuts (cos/sin of n phi by recurrence, later passes by
    rotation through the small angle they moved, the tone and a constant rate's first
    guess from grid tables; issue 27) give the direct evaluation's numbers. 8.6e-4
    moves phi ~1e-3 rad a pass (rotated); 2e-2 more than 1e-2 rad (evaluated afresh).
    Ramps and a reversal included."""
    mains = Mains(50.0, 2.0e-3, 30.0)
    truth = AxisTruth(rate_bias_rel=3e-7, mains=mains, harmonics=(
        Harmonic(1, amplitude_rel, 40.0), Harmonic(2, amplitude_rel / 5, -70.0),
        Harmonic(5, amplitude_rel / 10, 10.0)))
    ax = AxisModel(truth, rate_hz=1000.0, seed=3)
    chunks = _record(ax)
    ax.command_rate(1.0, 400.0, 100.0)
    ax.command_rate(60.0, -90.0, 50.0)
    ax.advance_to(100.0)
    c = {f: np.concatenate([getattr(x, f) for x in chunks])
         for f in ("t_s", "rate_cmd_dps", "w_true_dps", "phi_deg")}
    w, phi = _fixed_point_directly(truth, c["t_s"], c["rate_cmd_dps"], ax.block_samples,
                                   1.0 / ax.rate_hz)
    np.testing.assert_allclose(c["w_true_dps"], w, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(c["phi_deg"], phi, rtol=1e-14, atol=1e-9)
