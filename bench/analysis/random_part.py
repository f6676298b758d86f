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

A corrected figure is a difference of two estimated variances, raw^2 - floor^2, whose
truth may be near zero (a table far quieter than its FOG): there the linear propagation
fails. Its interval comes from a JCGM 101 Monte Carlo (`VarianceDifference`): each variance
is drawn from its state of knowledge, s^2 nu / chi2_nu (nu the degrees of freedom of its
estimate: samples minus fitted parameters for the raw figure, 2/3 of the successive
differences for the floor), and the difference's 2.5 % and 97.5 % quantiles bound it.
`resolved` only when the 2.5 % quantile is above zero; then value with [lower, upper], else
"< L" with L the square root of the 97.5 % quantile (`corrected_upper_rel`), never below
what the floor's own uncertainty allows to be seen. The same holds for the figures
averaged over 1, 10, 360 deg (blocks - 1 degrees of freedom for the raw one).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from bench.analysis.allan import white_noise
from bench.analysis.angle import FogCalibration
from bench.analysis.coverage import chi2_ppf, coverage_factor
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

    @property
    def dof(self) -> float:
        """Effective degrees of freedom of sigma^2: 2 / (relative variance) = 2 terms / 3."""
        return 2.0 * self.terms / 3.0


#: the Monte Carlo's draws and its fixed seed: a run's figures depend on its data alone
MC_DRAWS = 40_000
MC_SEED = 20_221
#: two-sided level of the corrected figures' intervals; the limit "< L" is one-sided at
#: (1 + LEVEL) / 2, the same level as the interval's upper end
LEVEL = 0.95


@dataclass(frozen=True)
class VarianceDifference:
    """sqrt(raw^2 - floor^2) with its JCGM 101 interval (docs/method.md A5)."""

    value: float            # sqrt(max(raw^2 - floor^2, 0))
    lower: float            # sqrt of the difference's (1 - LEVEL) / 2 quantile (>= 0)
    upper: float            # sqrt of the (1 + LEVEL) / 2 quantile: the limit L
    resolved: bool          # the lower quantile is above zero
    ustd: float = math.nan  # standard deviation of sqrt(max(draw, 0)): the figure's u

    @property
    def u(self) -> float | None:
        """Half-width that covers [lower, upper] around the value (resolved only)."""
        if not self.resolved:
            return None
        return max(self.upper - self.value, self.value - self.lower)

    @classmethod
    def of(cls, raw: float, raw_dof: float, floor: float, floor_dof: float
           ) -> VarianceDifference:
        diff = raw * raw - floor * floor
        value = math.sqrt(max(diff, 0.0))
        if not (raw_dof > 0 and math.isfinite(floor)):
            return cls(value, 0.0, math.inf, False, math.inf)
        rng = np.random.default_rng(MC_SEED)
        x_raw = raw_dof / rng.chisquare(raw_dof, MC_DRAWS)
        v_floor = (floor * floor * floor_dof / rng.chisquare(floor_dof, MC_DRAWS)
                   if floor_dof > 0 and math.isfinite(floor_dof) else floor * floor)
        draws = raw * raw * x_raw - v_floor
        lo = float(np.quantile(draws, (1 - LEVEL) / 2))
        # JCGM 101 7.6: the output's standard uncertainty is the draws' standard deviation
        ustd = float(np.std(np.sqrt(np.maximum(draws, 0.0)), ddof=1))
        # the limit never below the sensitivity: a raw variance under the floor by chance
        # gives the limit an observed zero difference would, not a tighter one (or zero)
        top = max(raw, floor)
        hi = float(np.quantile(top * top * x_raw - v_floor, (1 + LEVEL) / 2))
        return cls(value, math.sqrt(max(float(lo), 0.0)), math.sqrt(max(float(hi), 0.0)),
                   bool(lo > 0), ustd)


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
    floor_dof: float = math.inf    # of the FOG floor's variance
    dof: float = 0.0               # of the block means' variance: blocks less 1 per
    #                                calibrated window, 2 per window with its own bias

    @property
    def u_rel(self) -> float | None:
        """U of the std of the block means (chi-square, `std_interval_u_rel`)."""
        return std_interval_u_rel(self.instability_rel, self.blocks, self.dof)

    @property
    def measured_resolved(self) -> bool:
        """The measured figure stands above the FOG's floor over the window (D2)."""
        return above_floor(self.instability_rel, self.u_rel, self.floor_rel)[0]

    @property
    def measured_upper_rel(self) -> float | None:
        """L = value + U, never below the floor: the measured figure's limit (D2)."""
        return above_floor(self.instability_rel, self.u_rel, self.floor_rel)[1]

    @cached_property
    def difference(self) -> VarianceDifference | None:
        """The corrected figure's Monte Carlo (JCGM 101), run once: its four figures
        (resolved, upper, lower, ustd) are read from it, each by the result, the
        certificate and the station, and a run of 40 000 draws costs ~10 ms (the paper
        ladder's 72 averaged figures, read four times each: ~3 s of the run's end). Its
        seed is fixed, so the one run gives the numbers every run gave."""
        s, n = self.instability_rel, self.blocks
        if s is None or n < 2 or self.dof < 1 or not math.isfinite(self.floor_rel):
            return None
        return VarianceDifference.of(s, self.dof, self.floor_rel, self.floor_dof)

    @property
    def resolved(self) -> bool | None:
        """The table's own part stands out of the FOG's averaged floor (A5, JCGM 101)."""
        d = self.difference
        return None if d is None else d.resolved

    @property
    def corrected_upper_rel(self) -> float | None:
        d = self.difference
        return None if d is None else d.upper

    @property
    def corrected_ustd_rel(self) -> float | None:
        """The corrected figure's standard uncertainty (JCGM 101 7.6: the draws' std)."""
        d = self.difference
        return None if d is None else d.ustd

    @property
    def ustd_rel(self) -> float | None:
        """The measured figure's standard uncertainty, U / k (docs/method.md D1, D2)."""
        big_u = self.u_rel
        return None if big_u is None else big_u / coverage_factor(self.dof)

    @property
    def corrected_lower_rel(self) -> float | None:
        d = self.difference
        return None if d is None else d.lower


def above_floor(value: float | None, big_u: float | None, floor: float | None
                ) -> tuple[bool, float | None]:
    """(resolved, L) of a measured standard deviation with a symmetric U against its floor
    (docs/method.md D2, the one rule): resolved when value - U > floor; otherwise it is
    stated '< L', L = value + U, never below the floor. L is None without a value and U."""
    if value is None or big_u is None or not (math.isfinite(value) and math.isfinite(big_u)):
        return False, None
    fl = floor if floor is not None and math.isfinite(floor) else 0.0
    return big_u > 0 and value - big_u > fl, max(value + big_u, fl)


def std_u_rel(std: float | None, n: int) -> float | None:
    """The normal approximation U = 2 s / sqrt(2 (n - 1)) of a standard deviation from n
    values: what a result without a stated U (an older run) is read with; the analysis
    states `std_interval_u_rel` instead."""
    if std is None or n < 2:
        return None
    return 2.0 * std / math.sqrt(2.0 * (n - 1))


def std_interval_u_rel(std: float | None, n: int, dof: float | None = None) -> float | None:
    """U of a standard deviation estimated from n independent normal values (dof n - 1
    unless stated), docs/method.md A2: the half-width that covers the chi-square 95 %
    interval [s sqrt(nu / chi2_0.975), s sqrt(nu / chi2_0.025)] on both sides. For many
    values it is 2 s / sqrt(2 nu); for few it is wider above (4 values: 2.7 s), where
    the normal approximation would leave the truth outside far more than 5 % of the time.
    The one place this formula lives."""
    nu = (n - 1) if dof is None else dof
    if std is None or nu < 1:
        return None
    if nu > 1e4:
        return 2.0 * std / math.sqrt(2.0 * nu)
    hi = std * math.sqrt(nu / chi2_ppf(0.025, nu))
    lo = std * math.sqrt(nu / chi2_ppf(0.975, nu))
    return max(hi - std, std - lo)


@dataclass(frozen=True)
class RandomPartResult:
    instability_rel: float               # std(Dw_rand) / |w_set|, at bandwidth_hz
    floor_rel: float
    floor_source: str
    corrected_rel: float                 # sqrt(max(0, raw^2 - floor^2))
    corrected_upper_rel: float           # the (1 + LEVEL) / 2 limit L (JCGM 101)
    resolved: bool
    bandwidth_hz: float
    std_dps: float                       # std of the random part, deg/s of table rate
    samples: int
    averaged: tuple[AveragedInstability, ...]
    corrected_lower_rel: float = 0.0     # the (1 - LEVEL) / 2 end of the interval
    corrected_u_rel: float | None = None  # half-width covering [lower, upper], resolved only
    floor_dof: float = math.inf
    raw_dof: float = 0.0                  # samples - fitted parameters (the MC's nu_raw)
    corrected_ustd_rel: float | None = None   # the MC draws' std (JCGM 101 7.6)

    @property
    def raw_U_rel(self) -> float | None:
        """U of the raw figure, a std from `samples` values (A5, `std_interval_u_rel`)."""
        return std_interval_u_rel(self.instability_rel, self.samples)

    @property
    def raw_ustd_rel(self) -> float | None:
        """The raw figure's standard uncertainty, U / k (its budget's u_c, D1)."""
        big_u = self.raw_U_rel
        return None if big_u is None else big_u / coverage_factor(self.samples - 1)

    @property
    def raw_resolved(self) -> bool:
        """The raw figure stands above the FOG's floor: raw - U > floor (D2); otherwise it
        is stated '< L' like the figures averaged over an angle."""
        return above_floor(self.instability_rel, self.raw_U_rel, self.floor_rel)[0]

    @property
    def raw_upper_rel(self) -> float | None:
        """L = raw + U, never below the floor (D2)."""
        return above_floor(self.instability_rel, self.raw_U_rel, self.floor_rel)[1]


def _a5_row_coefs(fit: DirectionFit, cal: FogCalibration, own_bias: frozenset[int]
                  ) -> list[np.ndarray]:
    """Row coefficients per window of the random part (docs/method.md A5), k times:
    f - w0 - d (t - t_ref) - Dw_sys*k minus its mean over the calibrated windows. A window
    in `own_bias` (a half from another session than the calibration's: its FOG bias and
    time axis are its own, docs/resume.md) keeps the constant and trend the fit gave it
    (its own mean is then removed, by the fit)."""
    coefs: list[np.ndarray] = []
    total, n = 0.0, 0
    for w, ws in enumerate(fit.sums):
        win = ws.win
        c = fit.row_coef(w)                      # shared rows: harmonics and mains
        if win.index not in own_bias:
            d = cal.drift_dps_per_s
            # y = f - y_centre and t = t_centre + (D / 2) tau, so the calibration's bias and
            # drift are a constant and a tau term in the window's own columns
            c[ROW_CONST] = cal.w0_dps + d * (win.t_centre_s - cal.t_ref_s) - ws.y_centre_dps
            c[ROW_TAU] = d * 0.5 * win.duration_s
            v = -c
            v[ROW_Y] = 1.0
            total += float(ws.gram[ROW_CONST] @ v)
            n += ws.n
        coefs.append(c)
    mean_raw = total / n if n else 0.0           # k * (mean of the random part)
    for ws, c in zip(fit.sums, coefs, strict=True):
        if ws.win.index not in own_bias:
            c[ROW_CONST] += mean_raw             # docs/method.md A5: minus the mean
    return coefs


def random_part(fit: DirectionFit, cal: FogCalibration, set_rate_dps: float,
                floor: NoiseFloor, sample_rate_hz: float,
                averaging_deg: Sequence[float] = (1.0, 10.0, 360.0),
                own_bias: frozenset[int] = frozenset()) -> RandomPartResult:
    coefs = _a5_row_coefs(fit, cal, own_bias)
    rss = 0.0
    for ws, c in zip(fit.sums, coefs, strict=True):
        v = -c
        v[ROW_Y] = 1.0
        rss += float(v @ ws.gram @ v)
    scale = 1.0 / abs(cal.k * set_rate_dps)
    var_raw = max(rss, 0.0) / (fit.n - 1)
    raw = math.sqrt(var_raw) * scale             # docs/method.md A5: std(Dw_rand) / |w_set|
    floor_rel = floor.sigma_dps * scale
    n_params = fit.n_params
    diff = VarianceDifference.of(raw, fit.n - n_params, floor_rel, floor.dof)
    averaged = tuple(_averaged(fit, coefs, scale, floor, a, own_bias)
                     for a in averaging_deg)
    return RandomPartResult(
        instability_rel=raw, floor_rel=floor_rel, floor_source=floor.source,
        corrected_rel=diff.value, corrected_upper_rel=diff.upper, resolved=diff.resolved,
        bandwidth_hz=sample_rate_hz / 2.0,
        std_dps=math.sqrt(var_raw) / abs(cal.k), samples=fit.n, averaged=averaged,
        corrected_lower_rel=diff.lower, corrected_u_rel=diff.u, floor_dof=floor.dof,
        raw_dof=float(fit.n - n_params),
        corrected_ustd_rel=diff.ustd if math.isfinite(diff.ustd) else None)


def _averaged(fit: DirectionFit, coefs: list[np.ndarray], scale: float, floor: NoiseFloor,
              angle_deg: float, own_bias: frozenset[int] = frozenset()
              ) -> AveragedInstability:
    """docs/method.md A5: the random part's means over blocks of angle_deg. The
    calibration (k, w0 and the drift from the half means, A3) fits each calibrated window's
    mean, and a window with a constant and trend of its own (`own_bias`) fits two: each
    takes that many degrees of freedom from the blocks' means (for 360 deg blocks, 4 turns
    in two windows of '+-+' leave 2, not 3): the dof says so, and the std is over it."""
    fine = fit.design.fine_bin_deg
    m = angle_deg / fine
    if angle_deg <= 0 or 360 % angle_deg or abs(m - round(m)) > 1e-9:
        raise ValueError(f"averaging angle {angle_deg} deg must divide 360 and be a "
                         f"multiple of the fine bin {fine} deg")
    means, counts = [], []
    own = 0
    for ws, c in zip(fit.sums, coefs, strict=True):
        r = block_sums(bin_residuals(ws, c), ws, angle_deg)
        n = block_sums(ws.bins[ROW_CONST], ws, angle_deg)
        keep = n > 0
        means.append(r[keep] / n[keep])
        counts.append(n[keep])
        own += ws.win.index in own_bias
    mu = np.concatenate(means)
    cnt = np.concatenate(counts)
    per_block = float(cnt.mean()) if cnt.size else 0.0
    floor_rel = floor.sigma_dps * scale / math.sqrt(per_block) if per_block else math.nan
    dof = mu.size - (len(fit.sums) - own) - 2 * own
    if mu.size < 2 or dof < 1:
        return AveragedInstability(float(angle_deg), None, floor_rel, None, int(mu.size),
                                   per_block, floor.dof, max(dof, 0))
    s = math.sqrt(float(np.sum((mu - mu.mean()) ** 2)) / dof) * scale
    return AveragedInstability(float(angle_deg), s, floor_rel,
                               math.sqrt(max(s * s - floor_rel * floor_rel, 0.0)),
                               int(mu.size), per_block, floor.dof, dof)
