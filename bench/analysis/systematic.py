"""The systematic intra-turn component (docs/method.md A4): harmonic fit and the binned estimator.

API
    solve_direction(sums: Sequence[WindowSums]) -> DirectionFit
    noise_inflation(fits, block_deg) -> NoiseInflation            # coloured-noise check
    harmonic_block_deg(design) / long_block_deg(design, total_turns) -> float
    harmonics_result(fit, k, k_u_std, set_rate_dps, inflation) -> tuple[HarmonicResult, ...]
    mains_result(fit, k, k_u_std, inflation) -> MainsResult | None
    binned_systematic(fit, cal, set_rate_dps, bin_deg, inflation) -> BinnedSystematic

Convention (CONTRACT §2, sims/stand.py): (w_true - w_set) / w_set = sum_h a_h cos(h phi + p_h),
phi the table angle in its positive sense from the zero mark; the mains tone is
A cos(2 pi f t + p) in deg/s of table rate, t on the stand's time axis.

Fit: one direction's windows share the harmonics and the mains tone; each window has its
own constant and linear trend (the FOG's bias and its drift, whatever the calibration
made of them). The model is fitted to the raw FOG, so the harmonic and mains
coefficients are k times the table's: dividing by k (from docs/method.md A3) gives the table's,
and k's uncertainty enters theirs.

Uncertainties: the least-squares covariance sigma^2 (A^T A)^-1 holds for white noise. To
stay honest under coloured noise (FOG flicker, table wander), the residual's sums over
angle blocks of about a quarter of the highest harmonic's period are compared with what
white noise gives; their ratio ("noise inflation", never below 1) scales the covariance.
Amplitude and phase uncertainties are first-order (delta method): fine when the
amplitude is well above its uncertainty. `detected` is the bench's one rule for a
magnitude (docs/method.md A4, D2) with a stated false-alarm rate: a tone (a harmonic order or
the mains line) has the coverage interval a +/- c u(a), c = sqrt(-2 ln alpha_1) the radius of
the chi-square (2 dof) joint test of its two coefficients at 1 - alpha_1, with
alpha_1 = 1 - (1 - DETECTION_FALSE_ALARM)^(1/m) (Sidak) for the m tones fitted in one
direction; it is `detected` when the interval's lower end a - c u(a) is above zero (for the
fit's isotropic coefficient covariance the same as q = (a, b) C^-1 (a, b)^T > c^2): the
chance that any order whose truth is zero is called detected is then DETECTION_FALSE_ALARM
(white or inflation-corrected noise). An undetected tone is reported as the upper limit
L = a + c u(a) (`amplitude_upper_*`), one-sided at 1 - alpha_1.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import cast

import numpy as np

from bench.analysis.angle import FogCalibration
from bench.analysis.sums import ROW_CONST, ROW_TAU, ROW_Y, Design, WindowSums

COVERAGE = 2.0
#: family-wise false-alarm rate of the tone detection over all orders tested in a direction
DETECTION_FALSE_ALARM = 0.05
_DIVISORS_360 = [d for d in range(1, 361) if 360 % d == 0]
MIN_LONG_BLOCKS = 32


@dataclass(frozen=True)
class HarmonicResult:
    order: int
    amplitude_rel: float
    amplitude_u_rel: float      # expanded, k = 2
    phase_deg: float            # in (-180, 180]
    phase_u_deg: float          # expanded, k = 2
    detected: bool              # a - c u(a) > 0 (A4, D2: `tone_interval`)
    amplitude_upper_rel: float = math.nan   # a + c u(a): the limit L when not detected
    interval_factor: float = math.nan       # c = sqrt(-2 ln alpha_1)


@dataclass(frozen=True)
class MainsResult:
    frequency_hz: float
    amplitude_dps: float
    amplitude_u_dps: float      # expanded, k = 2
    phase_deg: float
    phase_u_deg: float
    detected: bool              # a - c u(a) > 0 (A4, D2: `tone_interval`)
    significance: float = 0.0   # chi2 (2 dof) of the tone's coefficients
    source: str = "given"       # where frequency_hz comes from (set by the procedure)
    amplitude_upper_dps: float = math.nan   # a + c u(a): the limit L when not detected
    interval_factor: float = math.nan       # c = sqrt(-2 ln alpha_1)


@dataclass(frozen=True)
class BinnedSystematic:
    """The paper's estimator in the angle domain: mean calibrated rate per angle bin over
    all turns, minus w_set, over w_set."""

    bin_deg: float
    centres_deg: tuple[float, ...]
    deviation_rel: tuple[float, ...]
    u_rel: tuple[float, ...]     # expanded, k = 2, per bin
    peak_to_peak_rel: float


@dataclass(frozen=True)
class NoiseInflation:
    """Residual block-sum variance over the white-noise expectation (>= 1 when applied)."""

    block_deg: float
    blocks: int
    ratio: float

    @property
    def factor(self) -> float:
        """The variance factor applied: never below 1."""
        return max(1.0, self.ratio)


@dataclass(frozen=True, eq=False)
class DirectionFit:
    """The model fitted to one direction's windows."""

    sums: tuple[WindowSums, ...]
    design: Design
    coef: np.ndarray          # 2 per window (const, tau), then the shared rows
    cov_unit: np.ndarray      # (A^T A)^-1
    rss: float
    n: int

    @property
    def n_params(self) -> int:
        return self.coef.size

    @property
    def sigma_dps(self) -> float:
        """Residual standard deviation, raw FOG units."""
        return math.sqrt(self.rss / (self.n - self.n_params))

    def shared_index(self, row: int) -> int:
        return 2 * len(self.sums) + row - 3

    def row_coef(self, w: int) -> np.ndarray:
        """The coefficient of every buffer row for window w (0 for y)."""
        c = np.zeros(self.design.rows)
        c[ROW_CONST] = self.coef[2 * w]
        c[ROW_TAU] = self.coef[2 * w + 1]
        c[3:] = self.coef[2 * len(self.sums):]
        return c


def _global_index(design: Design, w: int, n_windows: int) -> np.ndarray:
    """Global parameter of each model row (rows without y) of window w."""
    rows = design.model_rows()
    return np.array([2 * w + r if r < ROW_Y else 2 * n_windows + r - 3 for r in rows])


def solve_direction(sums: Sequence[WindowSums]) -> DirectionFit:
    """Least squares from the windows' Gram matrices (normal equations, Cholesky)."""
    sums = tuple(sums)
    design = sums[0].design
    nw = len(sums)
    p = 2 * nw + design.rows - 3
    normal = np.zeros((p, p))
    rhs = np.zeros(p)
    yy = 0.0
    n = 0
    rows = design.model_rows()
    for w, ws in enumerate(sums):
        gi = _global_index(design, w, nw)
        g = ws.gram
        normal[np.ix_(gi, gi)] += g[np.ix_(rows, rows)]
        rhs[gi] += g[rows, ROW_Y]
        yy += g[ROW_Y, ROW_Y]
        n += ws.n
    if n <= p:
        raise ValueError(f"systematic fit: {n} samples for {p} parameters")
    # scale to unit diagonal: conditioning of sums of 1, tau and trig columns
    d = np.sqrt(np.diag(normal))
    if np.any(d == 0):
        raise ValueError("systematic fit: a model column is all zeros")
    scaled = normal / np.outer(d, d)
    import scipy.linalg  # here, not at the top: `bench validate` does not load scipy
    try:
        cf = scipy.linalg.cho_factor(scaled)
    except np.linalg.LinAlgError:
        raise ValueError("systematic fit: the harmonic model is singular for these samples "
                         "(too many harmonics for the FOG rate, or a mains frequency "
                         "aliased onto a harmonic?)") from None
    if np.linalg.cond(scaled) > 1e12:
        raise ValueError("systematic fit: the harmonic model is ill-conditioned for these "
                         "samples (mains frequency aliased onto a harmonic?)")
    coef = scipy.linalg.cho_solve(cf, rhs / d) / d
    cov_unit = scipy.linalg.cho_solve(cf, np.eye(p)) / np.outer(d, d)
    rss = float(yy - coef @ rhs)
    return DirectionFit(sums=sums, design=design, coef=coef, cov_unit=cov_unit,
                        rss=max(rss, 0.0), n=n)


def bin_columns(ws: WindowSums) -> np.ndarray:
    """Sum of every model column over each fine bin, in `Design.model_rows()` order.

    Exact for the constant, trend and mains columns (summed in the pass); for the
    harmonics, the bin's centre angle with the sinc factor of its width, times its count.
    """
    design = ws.design
    b = ws.bins
    cnt = b[ROW_CONST]
    cols = np.empty((len(design.model_rows()), cnt.size))
    i = 0
    for r in range(design.bin_rows):
        if r != ROW_Y:
            cols[i] = b[r]
            i += 1
    phi = np.radians(ws.bin_centres_deg())
    half = math.radians(design.fine_bin_deg) / 2
    for h in range(1, design.harmonics + 1):
        sinc = math.sin(h * half) / (h * half)
        cols[i] = sinc * cnt * np.cos(h * phi)
        cols[i + 1] = sinc * cnt * np.sin(h * phi)
        i += 2
    return cols


def bin_residuals(ws: WindowSums, row_coef: np.ndarray) -> np.ndarray:
    """Sum over each fine bin of y minus the model with the given row coefficients."""
    return cast(np.ndarray, ws.bins[ROW_Y] - row_coef[ws.design.model_rows()] @ bin_columns(ws))


def block_sums(values: np.ndarray, ws: WindowSums, block_deg: float) -> np.ndarray:
    """Add fine bins into blocks of block_deg, aligned with each turn's zero mark."""
    m = round(block_deg / ws.design.fine_bin_deg)
    return cast(np.ndarray, values.reshape(*values.shape[:-1], -1, m).sum(axis=-1))


def harmonic_block_deg(design: Design) -> float:
    """Blocks of about a quarter of the highest harmonic's period (multiples of the bin)."""
    target = 360.0 / (4 * max(design.harmonics, 1))
    ok = [d for d in _DIVISORS_360 if d >= design.fine_bin_deg and d <= target
          and abs(d / design.fine_bin_deg - round(d / design.fine_bin_deg)) < 1e-9]
    return float(ok[-1]) if ok else design.fine_bin_deg


def long_block_deg(design: Design, total_turns: int) -> float:
    """The longest blocks that still give MIN_LONG_BLOCKS blocks over the pair."""
    ok = [d for d in _DIVISORS_360 if d >= design.fine_bin_deg
          and abs(d / design.fine_bin_deg - round(d / design.fine_bin_deg)) < 1e-9
          and total_turns * 360 // d >= MIN_LONG_BLOCKS]
    return float(ok[-1]) if ok else design.fine_bin_deg


def noise_inflation(fits: Sequence[DirectionFit], block_deg: float) -> NoiseInflation:
    """Pooled over the pair: observed sum of squared block residual sums over its
    white-noise expectation sigma^2 * sum_b (n_b - a_b^T (A^T A)^-1 a_b), a_b the block's
    column sums (the fit's leverage on the block)."""
    num, den, blocks = 0.0, 0.0, 0
    for fit in fits:
        s2 = fit.sigma_dps ** 2
        if s2 == 0:            # a noise-free record: nothing to inflate
            continue
        for w, ws in enumerate(fit.sums):
            cols = block_sums(bin_columns(ws), ws, block_deg)
            r = block_sums(bin_residuals(ws, fit.row_coef(w)), ws, block_deg)
            gi = _global_index(fit.design, w, len(fit.sums))
            cu = fit.cov_unit[np.ix_(gi, gi)]
            lev = np.einsum("ib,ij,jb->b", cols, cu, cols)
            nb = cols[0]                       # the constant column: samples per block
            keep = nb > 0
            num += float(np.sum(r[keep] ** 2)) / s2
            den += float(np.sum(nb[keep] - lev[keep]))
            blocks += int(keep.sum())
    ratio = num / den if den > 0 else 1.0
    return NoiseInflation(block_deg=block_deg, blocks=blocks, ratio=float(ratio))


def _amp_phase(a: float, b: float, cov: np.ndarray) -> tuple[float, float, float, float]:
    """x = a cos + b sin = A cos(. + p): A, u(A), p deg, u(p) deg (standard)."""
    amp = math.hypot(a, b)
    phase = math.degrees(math.atan2(-b, a))
    if amp == 0:
        return 0.0, math.sqrt(max(cov[0, 0], cov[1, 1])), 0.0, 180.0
    ja = np.array([a, b]) / amp
    jp = np.array([b, -a]) / amp ** 2
    u_amp = math.sqrt(max(float(ja @ cov @ ja), 0.0))
    u_ph = math.degrees(math.sqrt(max(float(jp @ cov @ jp), 0.0)))
    return amp, u_amp, phase, min(u_ph, 180.0)


def _pair_cov(fit: DirectionFit, row: int, scale: float, inflation: NoiseInflation
              ) -> tuple[float, float, np.ndarray]:
    i = fit.shared_index(row)
    a, b = fit.coef[i] * scale, fit.coef[i + 1] * scale
    cov = fit.cov_unit[i:i + 2, i:i + 2] * fit.sigma_dps ** 2 * inflation.factor * scale ** 2
    return a, b, cov


def tones_tested(design: Design) -> int:
    """How many tones one direction's detection tests: the harmonic orders and the mains."""
    return design.harmonics + (1 if design.has_mains else 0)


def detection_threshold(tests: int, false_alarm: float = DETECTION_FALSE_ALARM) -> float:
    """chi2 (2 dof) threshold of one tone so that m tests together alarm at `false_alarm`
    (Sidak): for 2 dof the quantile is closed form, -2 ln(alpha_1)."""
    alpha_1 = 1.0 - (1.0 - false_alarm) ** (1.0 / max(tests, 1))
    return -2.0 * math.log(alpha_1)


def tone_interval(amplitude: float, u_amplitude: float, tests: int
                  ) -> tuple[bool, float, float]:
    """(detected, L, c) of a tone (docs/method.md A4, D2): its amplitude's coverage interval
    is a +/- c u(a), c = sqrt(-2 ln alpha_1) the radius of the joint 2-dof test of its two
    coefficients for m = `tests` tones (Sidak, DETECTION_FALSE_ALARM family-wise); detected
    when a - c u(a) > 0, else stated '< L', L = a + c u(a). u(a) is the amplitude's standard
    uncertainty (its budget's u_c)."""
    c = math.sqrt(detection_threshold(tests))
    return amplitude - c * u_amplitude > 0.0, amplitude + c * u_amplitude, c


def _significance(a: float, b: float, cov: np.ndarray) -> float:
    """q = v C^-1 v: chi2 with 2 dof when the tone's truth is zero."""
    v = np.array([a, b])
    try:
        return float(v @ np.linalg.solve(cov, v))
    except np.linalg.LinAlgError:
        return 0.0


def detection_dict(design: Design) -> dict[str, str | float]:
    """The rule as result.json states it beside the tones."""
    m = tones_tested(design)
    return {"rule": "chi-square (2 dof) test of each tone's two coefficients, Sidak-"
                    "corrected for the tones fitted in the direction",
            "family_false_alarm": DETECTION_FALSE_ALARM, "tones_tested": m,
            "chi2_threshold": detection_threshold(m)}


def harmonics_result(fit: DirectionFit, k: float, k_u_std: float, set_rate_dps: float,
                     inflation: NoiseInflation) -> tuple[HarmonicResult, ...]:
    """Relative harmonic amplitudes of the table rate, with expanded uncertainties."""
    design = fit.design
    out = []
    scale = 1.0 / (k * set_rate_dps)
    for h in range(1, design.harmonics + 1):
        a, b, cov_noise = _pair_cov(fit, design.row_harm + 2 * (h - 1), scale, inflation)
        v = np.array([a, b])
        cov = cov_noise + np.outer(v, v) * (k_u_std / k) ** 2   # k's share (relative)
        amp, u_amp, ph, u_ph = _amp_phase(a, b, cov)
        detected, upper, c = tone_interval(amp, u_amp, tones_tested(design))   # A4, D2
        out.append(HarmonicResult(order=h, amplitude_rel=amp, amplitude_u_rel=COVERAGE * u_amp,
                                  phase_deg=ph, phase_u_deg=min(COVERAGE * u_ph, 180.0),
                                  detected=detected, amplitude_upper_rel=upper,
                                  interval_factor=c))
    return tuple(out)


def mains_result(fit: DirectionFit, k: float, k_u_std: float, inflation: NoiseInflation
                 ) -> MainsResult | None:
    design = fit.design
    if not design.has_mains:
        return None
    a, b, cov_noise = _pair_cov(fit, design.row_mains, 1.0 / k, inflation)
    v = np.array([a, b])
    cov = cov_noise + np.outer(v, v) * (k_u_std / k) ** 2
    amp, u_amp, ph, u_ph = _amp_phase(a, b, cov)
    assert design.mains_hz is not None  # has_mains
    q = _significance(a, b, cov_noise)
    detected, upper, c = tone_interval(amp, u_amp, tones_tested(design))   # A4, D2
    return MainsResult(frequency_hz=float(design.mains_hz), amplitude_dps=amp,
                       amplitude_u_dps=COVERAGE * u_amp, phase_deg=ph,
                       phase_u_deg=min(COVERAGE * u_ph, 180.0),
                       detected=detected, significance=q, amplitude_upper_dps=upper,
                       interval_factor=c)


def binned_systematic(fit: DirectionFit, cal: FogCalibration, set_rate_dps: float,
                      bin_deg: float, inflation: NoiseInflation) -> BinnedSystematic:
    """docs/method.md A4, the paper's estimator, with angles from the zero marks."""
    design = fit.design
    m = round(bin_deg / design.fine_bin_deg)
    if m < 1 or abs(bin_deg / design.fine_bin_deg - m) > 1e-9 or 360 % bin_deg:
        raise ValueError(f"binned estimator: bin_deg {bin_deg} must divide 360 and be a "
                         f"multiple of the fine bin {design.fine_bin_deg}")
    nb = round(360 / bin_deg)
    n = np.zeros(nb)
    s = np.zeros(nb)
    for ws in fit.sums:
        win = ws.win
        b = ws.bins
        cnt = b[ROW_CONST]
        # sum of the calibrated rate per fine bin (docs/method.md A3: (w_fog - w0 - d (t - tr)) / k)
        t_sum = win.t_centre_s * cnt + 0.5 * win.duration_s * b[ROW_TAU]
        cal_sum = (b[ROW_Y] + (ws.y_centre_dps - cal.w0_dps) * cnt
                   - cal.drift_dps_per_s * (t_sum - cal.t_ref_s * cnt)) / cal.k
        per_turn_n = cnt.reshape(win.turns, nb, m).sum(axis=(0, 2))
        per_turn_s = cal_sum.reshape(win.turns, nb, m).sum(axis=(0, 2))
        if win.sign < 0:  # fine bins run in u; the angle runs the other way
            per_turn_n, per_turn_s = per_turn_n[::-1], per_turn_s[::-1]
        n += per_turn_n
        s += per_turn_s
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = s / n
        dev = (mean - set_rate_dps) / set_rate_dps   # docs/method.md A4: Dw_sys / w_set
        u = (COVERAGE * fit.sigma_dps * np.sqrt(inflation.factor / n)
             / abs(cal.k * set_rate_dps))
    centres = (np.arange(nb) + 0.5) * bin_deg
    ok = n > 0
    ptp = float(np.ptp(dev[ok])) if ok.any() else math.nan
    return BinnedSystematic(bin_deg=float(bin_deg), centres_deg=tuple(centres.tolist()),
                            deviation_rel=tuple(np.where(ok, dev, np.nan).tolist()),
                            u_rel=tuple(np.where(ok, u, np.nan).tolist()),
                            peak_to_peak_rel=ptp)
