"""Cross-calibration of the FOG against the counter, per +/- rate pair (docs/method.md A3).

API
    HalfMean(sign, fog_mean_dps, fog_mean_u_dps, counter_mean_dps, counter_mean_u_dps,
             t_centre_s, turns)
    DriftEstimate(dps_per_s, u_dps_per_s, source)          # standard uncertainty
    cross_calibrate(halves, *, drift=None, timebase_u_rel=0.0) -> CrossCalibration
    fit_turns(fog_mean_dps, counter_dps, t_s, weights) -> TurnFit  # per-turn model, drift

Model: w_fog = k * w_true + w0 + d * (t - t_ref). Every FOG mean is over exactly the turns
the counter timed, so the table's own rate variations (harmonics, noise, wander) are in
both means and cancel; what is left is the FOG's bias, drift and noise.

Two halves (+w then -w): the paper's eq. 5/6. A linear drift d moves k by
d (t+ - t-) / (W+ - W-) and leaves w0 unbiased at t_ref = (t- W+ - t+ W-) / (W+ - W-)
(the mid-time for W- = -W+). At low rates that leak is large (5 turns at 0.1 deg/s and
0.001 deg/s/h: 2.5 % of k), so when the caller gives a drift estimate (the slope of the
per-turn FOG means within the halves, `fit_turns`) k is corrected by it and the
estimate's uncertainty enters k's (method "eq5-6, drift-corrected"); `k_eq5` keeps the
value as the paper prints it.

Three or more halves with both signs (e.g. +w, -w, +w): weighted least squares of
F_h = k C_h + w0 + d (t_h - t_ref), so a linear drift cancels (docs/method.md A3, beyond the
paper). t_ref is the weighted mean time, where w0 and d are uncorrelated. With more than
three halves the residual chi^2 is checked and the uncertainties are scaled by the Birge
ratio when it exceeds 1 (a drift that is not linear then shows in the uncertainty).

Uncertainties: the FOG half means carry what the caller measured (robust to coloured
noise, see pair.py); the counter means their edge timing; the counter's timebase error
scales every counter rate alike, so it moves k (relative) and not w0. All reported
uncertainties are expanded, k = 2.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bench.analysis.angle import FogCalibration

COVERAGE = 2.0


@dataclass(frozen=True)
class HalfMean:
    """One half's means over its whole turns (standard uncertainties)."""

    sign: int
    fog_mean_dps: float
    fog_mean_u_dps: float
    counter_mean_dps: float
    counter_mean_u_dps: float
    t_centre_s: float
    turns: int


@dataclass(frozen=True)
class DriftEstimate:
    """A FOG bias drift estimate (standard uncertainty) and where it came from."""

    dps_per_s: float
    u_dps_per_s: float
    source: str


@dataclass(frozen=True)
class CrossCalibration:
    """k, w0 (at t_ref) and d with expanded uncertainties (k = 2)."""

    k: float
    k_u: float
    w0_dps: float
    w0_u_dps: float
    t_ref_s: float
    drift_dps_per_s: float
    drift_u_dps_per_s: float
    method: str          # "eq5-6" | "lsq-drift"
    drift_source: str
    chi2: float | None
    dof: int
    birge_ratio: float
    halves: tuple[HalfMean, ...]
    k_eq5: float | None = None   # eq. 5 as printed, before the drift correction

    def calibration(self) -> FogCalibration:
        return FogCalibration(self.k, self.w0_dps, self.drift_dps_per_s, self.t_ref_s)


def _wls(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Weighted least squares: coefficients, their covariance (from the weights), chi^2.

    Columns are scaled to unit size first: counter rates of 0.01 deg/s beside times of
    1e5 s would otherwise look singular."""
    scale = np.max(np.abs(x), axis=0)
    scale[scale == 0] = 1.0
    sw = np.sqrt(w)
    xw = (x / scale) * sw[:, None]
    normal = xw.T @ xw
    if np.linalg.cond(normal) > 1e12:
        raise ValueError("cross-calibration: the halves do not determine k, w0 and the "
                         "drift (need both signs and distinct times)")
    cov = np.linalg.inv(normal)
    beta = cov @ (xw.T @ (y * sw)) / scale
    cov = cov / np.outer(scale, scale)
    chi2 = float(np.sum(w * (y - x @ beta) ** 2))
    return beta, cov, chi2


def _two_halves(plus: HalfMean, minus: HalfMean, drift: DriftEstimate | None,
                timebase_u_rel: float, halves: tuple[HalfMean, ...]) -> CrossCalibration:
    fp, fm = plus.fog_mean_dps, minus.fog_mean_dps
    cp, cm = plus.counter_mean_dps, minus.counter_mean_dps
    dc = cp - cm
    k = (fp - fm) / dc                       # docs/method.md A3, eq. 5
    w0 = fp - k * cp                         # docs/method.md A3, eq. 6
    t_ref = (minus.t_centre_s * cp - plus.t_centre_s * cm) / dc
    # first-order propagation (partial derivatives of eq. 5 and 6)
    var_k = ((plus.fog_mean_u_dps ** 2 + minus.fog_mean_u_dps ** 2)
             + k * k * (plus.counter_mean_u_dps ** 2 + minus.counter_mean_u_dps ** 2)) / dc ** 2
    var_k += (k * timebase_u_rel) ** 2
    var_w0 = ((cm * plus.fog_mean_u_dps) ** 2 + (cp * minus.fog_mean_u_dps) ** 2
              + (k * cm * plus.counter_mean_u_dps) ** 2
              + (k * cp * minus.counter_mean_u_dps) ** 2) / dc ** 2
    d, u_d, source = 0.0, 0.0, "none: two halves, drift not estimated"
    method = "eq5-6"
    k_eq5 = k
    if drift is not None:
        d, u_d, source = drift.dps_per_s, drift.u_dps_per_s, drift.source
        # docs/method.md A3 beyond the paper: remove the linear drift's leak into eq. 5's k;
        # w0 of eq. 6 (with eq. 5's k) is already the bias at t_ref
        leak = (plus.t_centre_s - minus.t_centre_s) / dc
        k = k_eq5 - d * leak
        var_k += (u_d * leak) ** 2
        method = "eq5-6, drift-corrected"
    return CrossCalibration(
        k=float(k), k_u=COVERAGE * math.sqrt(var_k), w0_dps=float(w0),
        w0_u_dps=COVERAGE * math.sqrt(var_w0), t_ref_s=float(t_ref),
        drift_dps_per_s=float(d), drift_u_dps_per_s=COVERAGE * u_d, method=method,
        drift_source=source, chi2=None, dof=0, birge_ratio=1.0, halves=halves,
        k_eq5=float(k_eq5))


def _lsq_drift(halves: tuple[HalfMean, ...], timebase_u_rel: float) -> CrossCalibration:
    f = np.array([h.fog_mean_dps for h in halves])
    c = np.array([h.counter_mean_dps for h in halves])
    t = np.array([h.t_centre_s for h in halves])
    uf = np.array([h.fog_mean_u_dps for h in halves])
    uc = np.array([h.counter_mean_u_dps for h in halves])
    k = 1.0
    for _ in range(2):  # the counter's share of each point's variance depends on k
        w = 1.0 / (uf ** 2 + (k * uc) ** 2)
        t_ref = float(np.sum(w * t) / np.sum(w))
        x = np.column_stack([c, np.ones_like(c), t - t_ref])
        beta, cov, chi2 = _wls(x, f, w)    # docs/method.md A3 with drift: F = k C + w0 + d (t - t_ref)
        k = float(beta[0])
    dof = len(halves) - 3
    birge = math.sqrt(chi2 / dof) if dof > 0 else 1.0
    scale = max(1.0, birge)
    var_k = cov[0, 0] * scale ** 2 + (k * timebase_u_rel) ** 2
    return CrossCalibration(
        k=k, k_u=COVERAGE * math.sqrt(var_k), w0_dps=float(beta[1]),
        w0_u_dps=COVERAGE * scale * math.sqrt(cov[1, 1]), t_ref_s=t_ref,
        drift_dps_per_s=float(beta[2]),
        drift_u_dps_per_s=COVERAGE * scale * math.sqrt(cov[2, 2]), method="lsq-drift",
        drift_source="fitted across the halves", chi2=chi2 if dof > 0 else None, dof=dof,
        birge_ratio=birge, halves=halves)


def cross_calibrate(halves: Sequence[HalfMean], *, drift: DriftEstimate | None = None,
                    timebase_u_rel: float = 0.0) -> CrossCalibration:
    """Eq. 5/6 for two halves, the drift-cancelling fit for three or more."""
    hs = tuple(halves)
    signs = {h.sign for h in hs}
    if signs != {1, -1}:
        raise ValueError(f"cross-calibration needs halves of both signs, got signs "
                         f"{sorted(signs)}")
    for i, h in enumerate(hs):
        if not (h.fog_mean_u_dps > 0 and math.isfinite(h.fog_mean_u_dps)):
            raise ValueError(f"half {i}: FOG mean uncertainty must be > 0, got "
                             f"{h.fog_mean_u_dps}")
    if len(hs) == 2:
        plus = hs[0] if hs[0].sign > 0 else hs[1]
        minus = hs[1] if plus is hs[0] else hs[0]
        return _two_halves(plus, minus, drift, timebase_u_rel, hs)
    return _lsq_drift(hs, timebase_u_rel)


@dataclass(frozen=True)
class TurnFit:
    """Per-turn fit F_i = k C_i + w0 + d (t_i - t_ref): a provisional calibration for the
    angles, and the within-half drift for the two-half case."""

    k: float
    w0_dps: float
    drift_dps_per_s: float
    drift_u_dps_per_s: float   # standard; inf when the turns cannot separate drift
    t_ref_s: float

    def calibration(self) -> FogCalibration:
        d = self.drift_dps_per_s if math.isfinite(self.drift_u_dps_per_s) else 0.0
        return FogCalibration(self.k, self.w0_dps, d, self.t_ref_s)


def fit_turns(fog_mean_dps: np.ndarray, counter_dps: np.ndarray, t_s: np.ndarray,
              weights: np.ndarray) -> TurnFit:
    """Weighted fit of the per-turn means; weights 1 / variance of each turn's FOG mean."""
    if set(np.sign(counter_dps).astype(int)) != {1, -1}:
        raise ValueError("cross-calibration needs turns of both signs")
    t_ref = float(np.sum(weights * t_s) / np.sum(weights))
    dt = t_s - t_ref
    span = float(np.ptp(t_s))
    x = np.column_stack([counter_dps, np.ones_like(dt), dt])
    # drift is separable when the design has rank 3: enough turns at distinct times
    if counter_dps.size >= 3 and span > 0 and np.linalg.matrix_rank(
            x / np.array([np.max(np.abs(counter_dps)), 1.0, span])) == 3:
        beta, cov, chi2 = _wls(x, fog_mean_dps, weights)
        dof = counter_dps.size - 3
        scale = max(1.0, math.sqrt(chi2 / dof)) if dof > 0 else 1.0
        return TurnFit(float(beta[0]), float(beta[1]), float(beta[2]),
                       scale * math.sqrt(cov[2, 2]), t_ref)
    beta, _, _ = _wls(x[:, :2], fog_mean_dps, weights)
    return TurnFit(float(beta[0]), float(beta[1]), 0.0, math.inf, t_ref)
