"""The random intra-turn component and its instability (docs/method.md A5).

API
    NoiseFloor(sigma_dps, terms, source)                       # the FOG's white noise
    floor_from_static(static_fog_dps) -> NoiseFloor             # ADEV at tau0
    floor_from_fit(fit, max_samples) -> NoiseFloor              # the pair's own data
    random_part(fit, cal, set_rate_dps, floor, sample_rate_hz, averaging_deg)
        -> RandomPartResult

The random part is Dw_rand = w_true - Dw_sys(phi) - mean (docs/method.md A5), with w_true the
calibrated FOG (docs/method.md A3, including the linear bias drift the calibration found) and
Dw_sys the fitted harmonics and mains tone. Its standard deviation over |w_set| is the
raw intra-turn instability at the FOG's bandwidth (half its output rate). The FOG's own
noise is removed in quadrature, and the random part is also averaged over angles (1, 10,
360 deg by default: means over blocks aligned with the zero mark) to compare with a
vendor's rate-stability figure.

Floor sources: a static FOG record (Allan deviation at the sample interval), or, without
one, the white part of the pair's own residual (successive differences). The latter
counts all white noise at the sample rate as the FOG's, so the corrected figure is then
the table's non-white (slow) random rate only: say so next to it (`floor_source`).

A corrected figure is only meaningful when the raw variance exceeds the floor's by more
than the estimates' own scatter: `resolved` says whether it does, and
`corrected_upper_rel` bounds it (k = 2) when it does not: sqrt(max(diff, 0) + 2 u_diff),
so a raw variance that falls below the floor by chance never gives a limit tighter than
the measurement's sensitivity (a limit of zero would be one).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bench.analysis.allan import white_noise
from bench.analysis.angle import FogCalibration
from bench.analysis.sums import ROW_CONST, ROW_TAU, ROW_Y, residual_differences
from bench.analysis.systematic import DirectionFit, bin_residuals, block_sums

COVERAGE = 2.0
FLOOR_STATIC = "static record: Allan deviation at the FOG sample interval"
FLOOR_PAIR = ("pair's own data: white part of the residual (successive differences), "
              "all of it attributed to the FOG")


@dataclass(frozen=True)
class NoiseFloor:
    sigma_dps: float      # per sample, raw FOG units
    terms: int            # differences it was estimated from
    source: str

    @property
    def var_u(self) -> float:
        """Standard uncertainty of sigma^2 (white noise, overlapping differences)."""
        return math.sqrt(3.0 / self.terms) * self.sigma_dps ** 2


def floor_from_static(static_fog_dps: np.ndarray) -> NoiseFloor:
    sigma, pairs = white_noise(static_fog_dps)
    return NoiseFloor(sigma, pairs, FLOOR_STATIC)


def floor_from_fit(fit: DirectionFit, max_samples: int) -> NoiseFloor:
    total, pairs = 0.0, 0
    per_window = max(max_samples // len(fit.sums), 1)
    for w, ws in enumerate(fit.sums):
        t, p = residual_differences(ws, fit.row_coef(w), per_window)
        total += t
        pairs += p
    return NoiseFloor(math.sqrt(total / pairs / 2.0), pairs, FLOOR_PAIR)


@dataclass(frozen=True)
class AveragedInstability:
    """The random part averaged over blocks of angle_deg (std of block means / |w_set|)."""

    angle_deg: float
    instability_rel: float | None
    floor_rel: float               # the FOG's white floor averaged over the same blocks
    corrected_rel: float | None
    blocks: int
    samples_per_block: float

    @property
    def u_rel(self) -> float | None:
        """U (k = 2) of the std of `blocks` block means: s / sqrt(2 (n - 1)) each."""
        return std_u_rel(self.instability_rel, self.blocks)

    def _excess(self) -> tuple[float, float] | None:
        """(s^2 - floor^2, its standard uncertainty from the n block means' scatter)."""
        s, n = self.instability_rel, self.blocks
        if s is None or n < 2 or not math.isfinite(self.floor_rel):
            return None
        return s * s - self.floor_rel ** 2, math.sqrt(2.0 / (n - 1)) * s * s

    @property
    def resolved(self) -> bool | None:
        """The table's own part stands out of the FOG's averaged floor (k = 2, as A5)."""
        ex = self._excess()
        return None if ex is None else ex[0] > COVERAGE * ex[1]

    @property
    def corrected_upper_rel(self) -> float | None:
        """k = 2 upper limit of the floor-corrected figure, never below the sensitivity."""
        ex = self._excess()
        return None if ex is None else math.sqrt(max(ex[0], 0.0) + COVERAGE * ex[1])

    def to_dict(self) -> dict[str, object]:
        return {"angle_deg": self.angle_deg, "instability_rel": self.instability_rel,
                "u_rel": self.u_rel,
                "floor_rel": self.floor_rel, "corrected_rel": self.corrected_rel,
                "corrected_upper_rel": self.corrected_upper_rel, "resolved": self.resolved,
                "blocks": self.blocks, "samples_per_block": self.samples_per_block}


def std_u_rel(std: float | None, n: int) -> float | None:
    """U (k = 2) of a standard deviation estimated from n independent values (normal data:
    u(s) = s / sqrt(2 (n - 1)), docs/method.md A2). The one place this formula lives."""
    if std is None or n < 2:
        return None
    return 2.0 * std / math.sqrt(2.0 * (n - 1))


@dataclass(frozen=True)
class RandomPartResult:
    instability_rel: float               # std(Dw_rand) / |w_set|, at bandwidth_hz
    floor_rel: float
    floor_source: str
    corrected_rel: float                 # sqrt(max(0, raw^2 - floor^2))
    corrected_upper_rel: float           # k = 2 upper bound
    resolved: bool
    bandwidth_hz: float
    std_dps: float                       # std of the random part, deg/s of table rate
    samples: int
    averaged: tuple[AveragedInstability, ...]

    def to_dict(self) -> dict[str, object]:
        return {"instability_rel": self.instability_rel, "floor_rel": self.floor_rel,
                "floor_source": self.floor_source, "corrected_rel": self.corrected_rel,
                "corrected_upper_rel": self.corrected_upper_rel, "resolved": self.resolved,
                "bandwidth_hz": self.bandwidth_hz, "std_dps": self.std_dps,
                "samples": self.samples, "averaged": [a.to_dict() for a in self.averaged]}


def _a5_row_coefs(fit: DirectionFit, cal: FogCalibration) -> tuple[list[np.ndarray], float]:
    """Row coefficients per window of: f - w0 - d (t - t_ref) - Dw_sys*k, before removing
    the mean; and that model's residual sum over all samples."""
    coefs = []
    total = 0.0
    for w, ws in enumerate(fit.sums):
        win = ws.win
        c = fit.row_coef(w)                      # shared rows: harmonics and mains
        d = cal.drift_dps_per_s
        # y = f - y_centre and t = t_centre + (D / 2) tau, so the calibration's bias and drift
        # are a constant and a tau term in the window's own columns
        c[ROW_CONST] = cal.w0_dps + d * (win.t_centre_s - cal.t_ref_s) - ws.y_centre_dps
        c[ROW_TAU] = d * 0.5 * win.duration_s
        coefs.append(c)
        v = -c
        v[ROW_Y] = 1.0
        total += float(ws.gram[ROW_CONST] @ v)
    return coefs, total


def random_part(fit: DirectionFit, cal: FogCalibration, set_rate_dps: float,
                floor: NoiseFloor, sample_rate_hz: float,
                averaging_deg: Sequence[float] = (1.0, 10.0, 360.0)) -> RandomPartResult:
    coefs, total = _a5_row_coefs(fit, cal)
    mean_raw = total / fit.n                     # k * (mean of the random part so far)
    rss = 0.0
    for ws, c in zip(fit.sums, coefs, strict=True):
        c[ROW_CONST] += mean_raw                 # docs/method.md A5: minus the mean
        v = -c
        v[ROW_Y] = 1.0
        rss += float(v @ ws.gram @ v)
    scale = 1.0 / abs(cal.k * set_rate_dps)
    var_raw = max(rss, 0.0) / (fit.n - 1)
    raw = math.sqrt(var_raw) * scale             # docs/method.md A5: std(Dw_rand) / |w_set|
    floor_rel = floor.sigma_dps * scale
    diff = raw ** 2 - floor_rel ** 2
    u_diff = math.hypot(math.sqrt(2.0 / fit.n) * raw ** 2, floor.var_u * scale ** 2)
    averaged = tuple(_averaged(fit, coefs, scale, floor, a) for a in averaging_deg)
    return RandomPartResult(
        instability_rel=raw, floor_rel=floor_rel, floor_source=floor.source,
        corrected_rel=math.sqrt(max(diff, 0.0)),
        # never below the sensitivity: a raw variance under the floor by chance (diff < 0)
        # gives the limit a zero difference would, not a tighter one (or zero)
        corrected_upper_rel=math.sqrt(max(diff, 0.0) + COVERAGE * u_diff),
        resolved=diff > COVERAGE * u_diff, bandwidth_hz=sample_rate_hz / 2.0,
        std_dps=math.sqrt(var_raw) / abs(cal.k), samples=fit.n, averaged=averaged)


def _averaged(fit: DirectionFit, coefs: list[np.ndarray], scale: float, floor: NoiseFloor,
              angle_deg: float) -> AveragedInstability:
    fine = fit.design.fine_bin_deg
    m = angle_deg / fine
    if angle_deg <= 0 or 360 % angle_deg or abs(m - round(m)) > 1e-9:
        raise ValueError(f"averaging angle {angle_deg} deg must divide 360 and be a "
                         f"multiple of the fine bin {fine} deg")
    means, counts = [], []
    for ws, c in zip(fit.sums, coefs, strict=True):
        r = block_sums(bin_residuals(ws, c), ws, angle_deg)
        n = block_sums(ws.bins[ROW_CONST], ws, angle_deg)
        keep = n > 0
        means.append(r[keep] / n[keep])
        counts.append(n[keep])
    mu = np.concatenate(means)
    cnt = np.concatenate(counts)
    per_block = float(cnt.mean()) if cnt.size else 0.0
    floor_rel = floor.sigma_dps * scale / math.sqrt(per_block) if per_block else math.nan
    if mu.size < 2:
        return AveragedInstability(float(angle_deg), None, floor_rel, None, int(mu.size),
                                   per_block)
    s = float(np.std(mu, ddof=1)) * scale
    return AveragedInstability(float(angle_deg), s, floor_rel,
                               math.sqrt(max(s * s - floor_rel * floor_rel, 0.0)),
                               int(mu.size), per_block)
