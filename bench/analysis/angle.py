"""The table angle of every FOG sample, from zero marks and the calibrated FOG (docs/method.md A4).

API
    FogCalibration(k, w0_dps, drift_dps_per_s=0.0, t_ref_s=0.0)
        .true_rate_dps(fog_dps, t_s)    # docs/method.md A3: (w_fog - w0 - d (t - t_ref)) / k
    turn_fraction(win, cal, c0, c1, i_c0) -> (u, segments, raw_integral)  # one chunk
    sample_angles_deg(win, cal) -> np.ndarray        # whole window, for plots and checks

Why not phi = j * w_set / f (the paper's index-to-angle map): it drifts by the rate error
times the elapsed time. Here each turn runs from one zero mark to the next and the angle
inside it is 360 * (integral of the calibrated rate since the mark) / (its integral over
the turn), so every turn spans exactly 360 deg, whatever the table's rate error, the FOG's
scale (k cancels in the ratio) or the mark's position between samples. For a negative
rotation the angle decreases in the table's positive sense: phi = 360 * (1 - u).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.analysis.window import Window


@dataclass(frozen=True)
class FogCalibration:
    """w_fog = k * w_true + w0 + d * (t - t_ref) (docs/method.md A3 with a linear bias drift)."""

    k: float
    w0_dps: float
    drift_dps_per_s: float = 0.0
    t_ref_s: float = 0.0

    def true_rate_dps(self, fog_dps: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        return (fog_dps - self.w0_dps - self.drift_dps_per_s * (t_s - self.t_ref_s)) / self.k

    def bias_integral(self, t_from_s: float, t_s: np.ndarray) -> np.ndarray:
        """Integral of w0 + d (t - t_ref) from t_from_s to t_s (exact for the trapezoid too)."""
        d = self.drift_dps_per_s
        out = self.w0_dps * (t_s - t_from_s)
        if d:
            out = out + 0.5 * d * ((t_s - self.t_ref_s) ** 2 - (t_from_s - self.t_ref_s) ** 2)
        return out


def raw_integral(win: Window, c0: int, c1: int, i_c0: float) -> np.ndarray:
    """Integral of the raw FOG from t_0 to each sample c0..c1-1, given it at sample c0."""
    f = win.f[c0:c1]
    if win.uniform_dt_s is not None:
        cs = np.cumsum(f)
        cs -= 0.5 * f[0]
        cs -= 0.5 * f
        cs *= win.uniform_dt_s
        cs += i_c0
        return cs
    t = win.t[c0:c1]
    areas = np.empty(f.size)
    areas[0] = i_c0
    np.add(f[:-1], f[1:], out=areas[1:])
    areas[1:] *= 0.5 * np.diff(t)
    return np.cumsum(areas, out=areas)


def step_integral(win: Window, n: int) -> float:
    """Trapezoid area between samples n and n + 1."""
    return float(0.5 * (win.f[n] + win.f[n + 1]) * (win.t[n + 1] - win.t[n]))


def turn_fraction(win: Window, cal: FogCalibration, c0: int, c1: int, i_c0: float
                  ) -> tuple[np.ndarray, list[tuple[int, int, int]], np.ndarray]:
    """Fraction u in [0, 1] of its turn for samples c0..c1-1; the turns in the chunk as
    (turn, first, end) sample offsets from c0; and the raw integral at each sample (the
    caller carries it to the next chunk)."""
    t = win.t[c0:c1]
    u = raw_integral(win, c0, c1, i_c0)
    i_raw = u.copy()
    e = win.edges_s
    e_cal = win.edge_int - cal.bias_integral(e[0], e)
    j0 = int(np.searchsorted(win.turn_start, c0, "right") - 1)
    j1 = int(np.searchsorted(win.turn_start, c1 - 1, "right") - 1)
    segs = []
    u -= cal.bias_integral(e[0], t)
    for j in range(j0, j1 + 1):
        a = max(int(win.turn_start[j]), c0) - c0
        b = min(int(win.turn_start[j + 1]), c1) - c0
        seg = u[a:b]
        seg -= e_cal[j]
        seg *= 1.0 / (e_cal[j + 1] - e_cal[j])
        segs.append((j, a, b))
    return u, segs, i_raw


def sample_angles_deg(win: Window, cal: FogCalibration) -> np.ndarray:
    """The angle of every sample in the window, deg in [0, 360) (one allocation of n)."""
    u, _, _ = turn_fraction(win, cal, win.s_lo, win.s_hi, win.i_first)
    phi = 360.0 * (u if win.sign > 0 else 1.0 - u)
    return np.mod(phi, 360.0)
