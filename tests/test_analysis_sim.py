"""Simulated +/- pairs for the analysis tests, straight from sims.stand.AxisModel (no twins).

`simulate_pair` commands the axis through the halves (ramp, settle, N whole turns timed
between zero marks), collects the FOG samples on the stand's grid and returns the
HalfRecords the engine would build, with the truth beside them. The tests in this file
check the helper itself against the stand, so the other files can trust it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from bench.analysis import HalfRecord
from sims.stand import AxisModel, AxisTruth, FogTruth, Harmonic, Mains


def paper_axis(**over) -> AxisTruth:
    """The paper-like outer axis of the brief (docs/method.md A6)."""
    base = dict(
        rate_bias_rel=2e-6,
        harmonics=(Harmonic(1, 8.6e-4, 40.0),),
        mains=Mains(50.0, 2e-4, 0.0),
        rate_noise_dps=1e-4,
        turn_jitter_s=27e-9,
        fog=FogTruth(scale=1.0003, bias_dps=0.002, misalignment_deg=0.2, noise_dps=0.01,
                     bias_drift_dps_per_h=0.001),
    )
    base.update(over)
    return AxisTruth(**base)


@dataclass
class SimPair:
    truth: AxisTruth
    rate_dps: float
    fog_rate_hz: float
    halves: list[HalfRecord]
    true_edges: list[np.ndarray]     # the stand's true zero-mark times per half
    phi_deg: np.ndarray | None       # true angle of every sample (when kept)
    w_true_dps: np.ndarray | None

    def true_rate_error(self, sign: int) -> float:
        """(mean - set) / set from the true zero-mark times of the halves of that sign."""
        n = sum(e.size - 1 for h, e in zip(self.halves, self.true_edges, strict=True)
                if h.sign == sign)
        d = sum(e[-1] - e[0] for h, e in zip(self.halves, self.true_edges, strict=True)
                if h.sign == sign)
        mean = sign * 360.0 * n / d
        return (mean - sign * self.rate_dps) / (sign * self.rate_dps)


def simulate_pair(truth: AxisTruth, rate_dps: float, turns: int, order: str = "+-+",
                  fog_rate_hz: float = 1000.0, seed: int = 1, accel_dps2: float = 100.0,
                  settle_s: float = 0.5, keep_truth: bool = False) -> SimPair:
    model = AxisModel(truth, fog_rate_hz, seed)
    fog: list[np.ndarray] = []
    phi: list[np.ndarray] = []
    wtr: list[np.ndarray] = []

    def listen(chunk) -> None:
        fog.append(chunk.fog_dps)
        if keep_truth:
            phi.append(chunk.phi_deg)
            wtr.append(chunk.w_true_dps)

    model.listeners.append(listen)
    period = 360.0 / rate_dps
    t = 0.0
    edges, true_edges, signs = [], [], []
    for ch in order:
        sign = 1 if ch == "+" else -1
        seg = model.command_rate(t, sign * rate_dps, accel_dps2)
        t_ok = seg.t_end_s + settle_s
        t_end = t_ok + (turns + 1.5) * period
        model.advance_to(t_end)
        zm = model.zero_marks(t_ok, t_end)
        assert zm.t_edge_s.size >= turns + 1 and np.all(zm.sense == sign)
        edges.append(zm.t_edge_s[:turns + 1].copy())
        true_edges.append(zm.t_true_s[:turns + 1].copy())
        signs.append(sign)
        t = float(zm.t_edge_s[turns]) + 0.1 * period
    model.advance_to(t + 1.0)
    f = np.concatenate(fog)
    t_all = np.arange(f.size) / fog_rate_hz
    halves = [HalfRecord(s, e, t_all, f) for s, e in zip(signs, edges, strict=True)]
    return SimPair(truth, rate_dps, fog_rate_hz, halves, true_edges,
                   np.concatenate(phi) if keep_truth else None,
                   np.concatenate(wtr) if keep_truth else None)


def test_helper_halves_are_whole_turns_of_the_stand():
    sp = simulate_pair(paper_axis(), 100.0, 3, order="+-", seed=3, keep_truth=True)
    for h, te in zip(sp.halves, sp.true_edges, strict=True):
        # edges jitter by 27 ns around the truth; the angle advances 360 deg per turn
        assert np.all(np.abs(h.edge_times_s - te) < 2e-7)
        idx = np.round(te * sp.fog_rate_hz).astype(int)
        turns = np.diff(sp.phi_deg[idx]) * h.sign
        assert np.allclose(turns, 360.0, atol=0.2)
    assert sp.halves[0].sign == 1 and sp.halves[1].sign == -1
    assert math.isclose(sp.true_rate_error(1), 2e-6, abs_tol=5e-6)


@pytest.mark.timeout(30)
def test_helper_fog_follows_its_truth():
    sp = simulate_pair(paper_axis(), 100.0, 2, order="+", seed=4, keep_truth=True)
    fog = sp.truth.fog
    t = sp.halves[0].fog_t_s
    model = fog.k * sp.w_true_dps + fog.bias_at(t)
    resid = sp.halves[0].fog_dps - model
    assert abs(np.std(resid) - fog.noise_dps) < 0.05 * fog.noise_dps
