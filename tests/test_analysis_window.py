"""Exact FOG integrals over whole turns (docs/method.md A3: the FOG mean over exactly the
turns the counter timed), wherever the edges fall between samples."""

from __future__ import annotations

import numpy as np
import pytest

from bench.analysis import HalfRecord, Window


def linear_record(t: np.ndarray, edges: np.ndarray) -> HalfRecord:
    # f = 3 + 0.5 t: the linear interpolant is exact, so must be every integral
    return HalfRecord(1, edges, t, 3.0 + 0.5 * t)


def integral(a: float, b: float) -> float:
    return 3.0 * (b - a) + 0.25 * (b * b - a * a)


@pytest.mark.parametrize("gaps", [False, True])
def test_edge_integrals_are_exact(gaps):
    t = np.arange(0, 20_000) / 1000.0
    if gaps:
        t = np.delete(t, np.r_[3000:3050, 9000:9001, 15500:15900])
    edges = np.array([1.23456, 5.0000004, 9.0004, 13.9999, 17.77777])
    w = Window.from_record(linear_record(t, edges), 0, chunk=4096)
    assert (w.uniform_dt_s is None) == gaps
    for j, e in enumerate(edges):
        assert w.edge_int[j] == pytest.approx(integral(edges[0], e), abs=1e-9)
    assert w.fog_mean_dps == pytest.approx(integral(edges[0], edges[-1]) / w.duration_s,
                                           abs=1e-12)
    assert np.allclose(w.turn_fog_mean_dps, 3.0 + 0.5 * w.turn_centres_s, atol=1e-9)
    assert w.turn_start[0] == np.searchsorted(t, edges[0])
    assert w.n_samples == np.count_nonzero((t >= edges[0]) & (t <= edges[-1]))


def test_fog_must_cover_the_turns():
    t = np.arange(0, 1000) / 100.0
    with pytest.raises(ValueError, match="half 2: FOG samples .* do not cover"):
        Window.from_record(linear_record(t, np.array([1.0, 5.0, 12.0])), 2)


def test_turn_without_samples():
    t = np.arange(0, 100) / 10.0
    with pytest.raises(ValueError, match="a turn holds no FOG sample"):
        Window.from_record(linear_record(t, np.array([1.0, 1.01, 1.02])), 0)
