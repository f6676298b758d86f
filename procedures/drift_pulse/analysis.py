"""Gyro drift by alternating-sign controlled precession (docs/method.md B, seed 004).

One cycle: a torque-sensor pulse of duration Tc, then the same pulse with the opposite
sign; the command angle sensor's output U(t) is integrated with the sign of the active
pulse, and

    U_int = int_0^Tc U dt - int_Tc^2Tc U dt = -k_as w Tc^2 + k_as * control term
    w     = -U_int / (k_as Tc^2) + a * c_shape                          (docs/method.md B)

where c_shape = 2 int_0^1 G du - G(1) is zero for shapes symmetric in time (rectangular,
triangular) and a is the precession amplitude, fitted from U(t) itself for the others.
The integral is the trapezoid rule over samples that lie on the pulse edges.

Beyond the paper. The edges are where the pulses are, not where the digitizer thinks
they are: a start offset tau between the digitizer's samples and the pulses leaves
2 a G(1) tau / Tc in w (a half sample at 2 kHz, 0.5 deg/s, 5 s: 0.18 deg/h, docs/method.md B),
and it looks like own drift. So every cycle is also fitted with the model
U = c0 + c1 t + b P(t - tau) (P the unit pulse-pair angle), the offsets are pooled over
the cycles, and the integration windows are put where the pulses are; the offset and its
uncertainty are reported, and the uncorrected (nominal-edge) figure beside the corrected
one, so a shifted digitizer is seen, not silently absorbed.

Then the 0/180 deg separation into own and apparent drift (a least-squares fit over
positions, which is (w0 + w180)/2 and (w0 - w180)/2 for the two default positions), the
azimuth from two horizontal axes, and an uncertainty budget per figure: the
cycle-to-cycle scatter (type A) and the stated error sources (type B).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from msgspec import UNSET

from bench.analysis.coverage import coverage_factor
from bench.report.budget import Budget
from bench.report.conformity import judge
from drivers.units import EARTH_RATE_DPH, SECONDS_PER_HOUR
from procedures.drift_pulse.budgets import (
    AxisInputs,
    CorrectionInput,
    PositionInput,
    apparent_budget,
    azimuth_budget,
    earth_budget,
    own_budget,
)
from procedures.drift_pulse.result import (
    AxisFigures,
    CycleFigures,
    DriftCheck,
    DriftFigures,
    EarthRateCheck,
    ExampleCycle,
    OwnDriftCheck,
    PositionFigures,
    StartOffsetFigures,
)
from procedures.drift_pulse.shapes import SHAPES as SHAPES
from procedures.drift_pulse.shapes import PulseShape as PulseShape
from procedures.drift_pulse.shapes import pulse_shape as pulse_shape

DETECTION_Z = 3.0
#: a cycle whose fitted precession is off the median by this factor had no proper pulse
MIN_AMPLITUDE_REL = 0.5

#: input axis of each platform gyro relative to the X axis (docs/method.md B convention)
HORIZONTAL_OFFSET_DEG = {"x": 0.0, "y": 90.0}
VERTICAL_GYROS = ("z",)


# -- one cycle ---------------------------------------------------------------------------
@dataclass(frozen=True)
class CycleRecord:
    """One pulse pair's angle-sensor record.

    Sample k was taken at first_sample_s + k * sample_interval_s, on a time axis whose
    zero is the nominal start of the first pulse (the sample's centroid: an integrating
    digitizer's reading belongs to the middle of its aperture).
    """

    u_v: np.ndarray
    sample_interval_s: float
    first_sample_s: float
    pulse_s: float
    t_start_s: float = 0.0          # bench time of the nominal first edge
    table_deg: float = 0.0          # the position the cycle was measured at
    timing_only: bool = False       # a large-amplitude cycle that only locates the pulses

    @property
    def times_s(self) -> np.ndarray:
        return self.first_sample_s + np.arange(self.u_v.size) * self.sample_interval_s


def _antiderivative(t: np.ndarray, u: np.ndarray, x: np.ndarray) -> np.ndarray:
    """int_{t0}^{x} of the samples' linear interpolant: the trapezoid rule, exactly."""
    if x.min() < t[0] - 1e-12 or x.max() > t[-1] + 1e-12:
        raise ValueError(f"the record ({t[0]:.6f} .. {t[-1]:.6f} s) does not cover the "
                         f"integration edges ({x.min():.6f} .. {x.max():.6f} s): record "
                         f"more samples before and after the pulses")
    cum = np.concatenate(([0.0], np.cumsum(0.5 * (u[1:] + u[:-1]) * np.diff(t))))
    k = np.clip(np.searchsorted(t, x, side="right") - 1, 0, t.size - 2)
    f = x - t[k]
    ux = u[k] + (u[k + 1] - u[k]) * f / (t[k + 1] - t[k])
    integral: np.ndarray = cum[k] + 0.5 * f * (u[k] + ux)
    return integral


def signed_integral(t_s: np.ndarray, u_v: np.ndarray, start_s: float, pulse_s: float
                    ) -> float:
    """U_int = int_s^{s+Tc} U dt - int_{s+Tc}^{s+2Tc} U dt, trapezoid (docs/method.md B).

    With the edges on samples this is the plain trapezoid rule over each half; off the
    samples the partial intervals are integrated on the same linear interpolant.
    """
    edges = np.array([start_s, start_s + pulse_s, start_s + 2.0 * pulse_s])
    f0, f1, f2 = _antiderivative(np.asarray(t_s, float), np.asarray(u_v, float), edges)
    return float(2.0 * f1 - f0 - f2)


@dataclass(frozen=True)
class OffsetFit:
    """Least-squares fit of U = c0 + c1 t + b P(t - offset) over one cycle."""

    offset_s: float
    offset_u_s: float          # standard uncertainty from the fit's residuals
    amplitude_v_per_dps: float  # b = k_as * a: U per unit pair angle
    residual_rms_v: float
    converged: bool


def fit_offset(record: CycleRecord, shape: PulseShape, max_iter: int = 12) -> OffsetFit:
    """Where the pulses are in the record: Gauss-Newton on the offset, the rest linear.

    The fit uses the nominal window [0, 2 Tc]: over it a +/- amplitude mismatch is
    absorbed by the linear and pulse terms (it cannot be told from drift there, docs/method.md
    B), so it does not bias the offset.
    """
    t = record.times_s
    tc = record.pulse_s
    sel = (t >= -1e-9) & (t <= 2.0 * tc + 1e-9)
    t, u = t[sel], np.asarray(record.u_v, float)[sel]
    if t.size < 8:
        raise ValueError("too few samples inside the pulse pair to fit it")
    ts = t / tc  # conditioning

    def linearised(tau: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Linear coefficients at this offset, residuals, Jacobian [1, t, P, d/dtau]."""
        p = shape.pair_angle(t - tau, tc)
        basis = np.column_stack((np.ones_like(t), ts, p))
        coef, *_ = np.linalg.lstsq(basis, u, rcond=None)
        jac = np.column_stack((basis, -coef[2] * shape.pair_rate(t - tau, tc)))
        return coef, u - basis @ coef, jac

    tau = 0.0
    converged = False
    for _ in range(max_iter):
        _, r, jac = linearised(tau)
        step, *_ = np.linalg.lstsq(jac, r, rcond=None)
        tau += float(np.clip(step[3], -0.1 * tc, 0.1 * tc))
        if abs(step[3]) < 1e-9 * tc:
            converged = True
            break
    coef, r, jac = linearised(tau)
    s2 = float(r @ r) / max(t.size - 4, 1)
    try:
        u_tau = math.sqrt(max(np.linalg.inv(jac.T @ jac)[3, 3] * s2, 0.0))
    except np.linalg.LinAlgError:
        u_tau = math.inf
    return OffsetFit(tau, u_tau, float(coef[2]), math.sqrt(s2), converged)


@dataclass(frozen=True)
class CycleResult:
    """One cycle's drift: with the edges where the pulses are, and at the nominal edges."""

    drift_dph: float               # edges at the pooled start offset (the estimate used)
    drift_nominal_dph: float       # edges at the nominal sample times (the paper's integrator)
    u_int_vs: float                # U_int at the corrected edges, V s
    amplitude_dps: float           # fitted precession amplitude a
    offset_s: float                # this cycle's own fitted start offset
    offset_u_s: float
    residual_rms_v: float
    t_start_s: float
    table_deg: float

    def figures(self) -> CycleFigures:
        return CycleFigures(drift_dph=float(self.drift_dph),
                            drift_nominal_dph=float(self.drift_nominal_dph),
                            u_int_vs=float(self.u_int_vs), ustd_int_vs=float(self.u_int_vs),
                            amplitude_dps=float(self.amplitude_dps),
                            offset_s=float(self.offset_s), offset_u_s=float(self.offset_u_s),
                            offset_ustd_s=float(self.offset_u_s),
                            residual_rms_v=float(self.residual_rms_v),
                            t_start_s=float(self.t_start_s), table_deg=float(self.table_deg))


def cycle_drift_dph(record: CycleRecord, shape: PulseShape, k_as_v_per_deg: float,
                    start_s: float, amplitude_dps: float) -> tuple[float, float]:
    """w = -U_int / (k_as Tc^2) + a c_shape, deg/h, and U_int (docs/method.md B)."""
    tc = record.pulse_s
    u_int = signed_integral(record.times_s, record.u_v, start_s, tc)
    w_dps = -u_int / (k_as_v_per_deg * tc * tc) + amplitude_dps * shape.control_coeff
    return w_dps * SECONDS_PER_HOUR, u_int


def example_cycle(record: CycleRecord, start_s: float, max_points: int = 1000
                  ) -> ExampleCycle:
    """One cycle for a plot: U(t) and the running signed integral, from the first edge.

    The integrator adds U over the first pulse and subtracts it over the second
    (docs/method.md B); it is shown decimated to at most `max_points`.
    """
    t = record.times_s - start_s
    u = np.asarray(record.u_v, float)
    tc = record.pulse_s
    sign = np.where(t < 0, 0.0, np.where(t < tc, 1.0, np.where(t <= 2 * tc, -1.0, 0.0)))
    su = sign * u
    integral = np.concatenate(([0.0], np.cumsum(0.5 * (su[1:] + su[:-1]) * np.diff(t))))
    step = max(1, int(math.ceil(t.size / max_points)))
    return ExampleCycle(t_s=tuple(t[::step].tolist()), u_v=tuple(u[::step].tolist()),
                        integral_vs=tuple(integral[::step].tolist()), tc_s=tc,
                        note="time from the first pulse edge (where the fit puts it)")


# -- statistics --------------------------------------------------------------------------
@dataclass(frozen=True)
class StartOffset:
    """The digitizer's start offset against the pulses, pooled over an axis's cycles."""

    offset_s: float
    offset_u_s: float              # standard uncertainty of the pooled value
    sample_interval_s: float
    cycles: int

    @property
    def samples(self) -> float:
        return self.offset_s / self.sample_interval_s

    @property
    def significant(self) -> bool:
        """Detected: more than 3 standard uncertainties from zero (a one-sample shift is
        a hundred or more); the integration is corrected by it either way."""
        return abs(self.offset_s) > DETECTION_Z * self.offset_u_s

    def figures(self) -> StartOffsetFigures:
        # U = t_95.45(cycles - 1) u (docs/method.md D1)
        expanded = coverage_factor(max(self.cycles - 1, 1)) * self.offset_u_s
        return StartOffsetFigures(offset_s=self.offset_s, offset_u_s=expanded,
                                  offset_U_s=expanded, offset_samples=self.samples,
                                  detected=self.significant, cycles=self.cycles)


def pool_offsets(fits: Sequence[OffsetFit], sample_interval_s: float) -> StartOffset:
    """Weighted mean of the cycles' offsets (timing cycles of large amplitude weigh most).

    Its u is the fits' own, scaled up by the Birge ratio when the cycles scatter more
    than their fits say (pulse timing jitter does that).
    """
    if not fits:
        raise ValueError("no cycles to pool the start offset over")
    tau = np.array([f.offset_s for f in fits])
    u = np.array([max(f.offset_u_s, 1e-15) for f in fits])
    w = 1.0 / u ** 2
    mean = float((w * tau).sum() / w.sum())
    internal = math.sqrt(1.0 / w.sum())
    birge = math.sqrt(float((w * (tau - mean) ** 2).sum()) / (tau.size - 1)) if tau.size > 1 \
        else 1.0
    return StartOffset(mean, internal * max(birge, 1.0), sample_interval_s, tau.size)


@dataclass(frozen=True)
class PositionMean:
    """The cycles at one turntable position."""

    table_deg: float
    drifts_dph: tuple[float, ...]
    t_mean_s: float

    @property
    def n(self) -> int:
        return len(self.drifts_dph)

    @property
    def mean_dph(self) -> float:
        return float(np.mean(self.drifts_dph))

    @property
    def std_dph(self) -> float:
        return float(np.std(self.drifts_dph, ddof=1)) if self.n > 1 else math.nan

    @property
    def u_dph(self) -> float:
        """Type A standard uncertainty of the mean, s / sqrt(n) with n - 1 degrees of
        freedom, not widened: the t-factor of the budget's nu_eff carries the few cycles
        (docs/method.md D1, one rule with the rate ladder); n >= 2 is needed."""
        if self.n < 2:
            return math.inf
        return self.std_dph / math.sqrt(self.n)

    def figures(self) -> PositionFigures:
        """The position mean as a budget input: its standard uncertainty and dof, no U of its
        own (docs/method.md D2)."""
        return PositionFigures(table_deg=self.table_deg, cycles=self.n,
                               mean_dph=self.mean_dph, std_dph=self.std_dph,
                               mean_ustd_dph=self.u_dph, dof=self.n - 1,
                               drifts_dph=self.drifts_dph)

    def as_input(self) -> PositionInput:
        return PositionInput(self.table_deg, self.mean_dph, self.u_dph, self.n)


def separate(positions: Sequence[PositionMean]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Own and apparent drift from the positions (docs/method.md B, as least squares).

    Model: w(theta) = own + c cos(theta) - s sin(theta), c the apparent drift at 0 deg.
    For 0 and 180 deg only this is own = (w0 + w180)/2, app = (w0 - w180)/2. With other
    angles s is fitted too (the turn's extra information, beyond the paper).
    Returns (estimates [own, app0(, s)], covariance, gain G) from the type A
    uncertainties: est = G w, so row i of G holds the sensitivities of estimate i to the
    position means (1/2, 1/2 and 1/2, -1/2 for 0 and 180 deg), the budget's c_i.
    """
    theta = np.radians([p.table_deg for p in positions])
    w = np.array([p.mean_dph for p in positions])
    var = np.array([p.u_dph ** 2 for p in positions])
    cols = [np.ones_like(theta), np.cos(theta)]
    sines = np.sin(theta)
    if np.any(np.abs(sines) > 1e-9):
        cols.append(-sines)
    a = np.column_stack(cols)
    if np.linalg.matrix_rank(a) < a.shape[1]:
        raise ValueError("the positions do not separate own and apparent drift: measure "
                         "at two positions 180 deg apart at least")
    if not np.all(np.isfinite(var)):
        raise ValueError("each position needs at least two cycles (for its scatter)")
    var = np.maximum(var, 1e-30)  # noise-free cycles
    wt = 1.0 / var
    cov = np.linalg.inv(a.T @ (a * wt[:, None]))
    gain = cov @ (a.T * wt)
    return gain @ w, cov, gain


# -- the stated error sources and the result --------------------------------------------
@dataclass(frozen=True)
class StatedErrors:
    """Type B sources, as the stand and procedure files state them."""

    k_as_u_rel: float = 0.0                   # standard uncertainty of k_as, relative
    pulse_mismatch_max_rel: float = 0.0       # |+/- amplitude mismatch| bound (rectangular)
    drift_random_walk_dph_per_rth: float = 0.0  # the gyro's own-drift random walk (its spec)
    turn_tolerance_deg: float = 0.0           # how far a turn may land from its angle
    #: the instrument corrections applied to this gyro's readings (issue 58): budget rows
    corrections: tuple[CorrectionInput, ...] = ()


@dataclass(frozen=True)
class AxisDrift:
    """One gyro's own and apparent drift, with U = k(nu_eff) u_c of the budget behind each
    (docs/method.md D1)."""

    gyro: str
    own_dph: float
    own_u_dph: float
    apparent_dph: float
    apparent_u_dph: float
    positions: tuple[PositionMean, ...]
    cycles: tuple[CycleResult, ...]
    start_offset: StartOffset
    own_nominal_dph: float                    # at the nominal edges, for comparison
    apparent_nominal_dph: float
    amplitude_dps: float
    inputs: AxisInputs
    own_budget: Budget
    apparent_budget: Budget | None
    vertical: bool = False
    example: ExampleCycle | None = None        # one cycle for the plot

    def figures(self) -> AxisFigures:
        """The axis's part of the model; each U's k and nu_eff from its budget (D1)."""
        app = self.apparent_budget
        return AxisFigures(
            own_dph=self.own_dph, own_u_dph=self.own_u_dph, own_U_dph=self.own_u_dph,
            apparent_dph=self.apparent_dph, apparent_u_dph=self.apparent_u_dph,
            apparent_U_dph=self.apparent_u_dph, own_nominal_edges_dph=self.own_nominal_dph,
            apparent_nominal_edges_dph=self.apparent_nominal_dph,
            amplitude_dps=self.amplitude_dps, vertical=self.vertical,
            start_offset=self.start_offset.figures(),
            budgets=tuple(b.record() for b in (self.own_budget, app) if b is not None),
            positions=tuple(p.figures() for p in self.positions),
            cycles=tuple(c.figures() for c in self.cycles), example_cycle=self.example,
            own_coverage_factor=self.own_budget.k, own_dof_eff=self.own_budget.dof_eff,
            apparent_coverage_factor=None if app is None else app.k,
            apparent_dof_eff=UNSET if app is None else app.dof_eff)


def analyze_axis(gyro: str, records: Sequence[CycleRecord], shape: PulseShape,
                 k_as_v_per_deg: float, stated: StatedErrors = StatedErrors(),
                 latitude_deg: float | None = None) -> AxisDrift:
    """Every cycle of one gyro at every position -> its own and apparent drift."""
    drift_records = [r for r in records if not r.timing_only]
    if not drift_records:
        raise ValueError(f"gyro {gyro}: no drift cycles")
    dt = records[0].sample_interval_s
    tc = records[0].pulse_s
    if any(r.sample_interval_s != dt or r.pulse_s != tc for r in records):
        raise ValueError(f"gyro {gyro}: every cycle needs the same sample interval and Tc")
    fits = {id(r): fit_offset(r, shape) for r in records}
    pooled = pool_offsets(list(fits.values()), dt)
    amplitude = float(np.median([fits[id(r)].amplitude_v_per_dps
                                 for r in drift_records])) / k_as_v_per_deg
    for i, r in enumerate(drift_records):
        a_i = fits[id(r)].amplitude_v_per_dps / k_as_v_per_deg
        if not MIN_AMPLITUDE_REL * abs(amplitude) <= abs(a_i) <= abs(amplitude) / MIN_AMPLITUDE_REL:
            raise ValueError(f"gyro {gyro}: cycle {i + 1} (at {r.table_deg:g} deg) shows a "
                             f"precession of {a_i:.3g} deg/s against {amplitude:.3g} deg/s in "
                             f"the others: its pulses did not reach the torque sensor as set")
    cycles = []
    for r in drift_records:
        f = fits[id(r)]
        a_dps = f.amplitude_v_per_dps / k_as_v_per_deg
        w, u_int = cycle_drift_dph(r, shape, k_as_v_per_deg, pooled.offset_s, a_dps)
        w_nom, _ = cycle_drift_dph(r, shape, k_as_v_per_deg, 0.0, a_dps)
        cycles.append(CycleResult(w, w_nom, u_int, a_dps, f.offset_s, f.offset_u_s,
                                  f.residual_rms_v, r.t_start_s, r.table_deg))

    def by_position(values: Callable[[CycleResult], float]) -> list[PositionMean]:
        out = []
        for deg in sorted({round(c.table_deg % 360.0, 9) for c in cycles}):
            sel = [c for c in cycles if abs(((c.table_deg - deg + 180) % 360) - 180) < 1e-6]
            out.append(PositionMean(deg, tuple(values(c) for c in sel),
                                    float(np.mean([c.t_start_s for c in sel]))))
        return out

    positions = by_position(lambda c: c.drift_dph)
    nominal = by_position(lambda c: c.drift_nominal_dph)
    vertical = gyro in VERTICAL_GYROS
    if vertical:
        if latitude_deg is None:
            raise ValueError("the vertical gyro's own drift needs the site latitude")
        w_v = EARTH_RATE_DPH * math.sin(math.radians(latitude_deg))
        all_w = [w for p in positions for w in p.drifts_dph]
        own, app = float(np.mean(all_w)) - w_v, w_v
        own_nom = float(np.mean([w for p in nominal for w in p.drifts_dph])) - w_v
        app_nom = w_v
        inputs_at: tuple[PositionInput, ...] = (PositionMean(0.0, tuple(all_w),
                                                             0.0).as_input(),)
        own_c: tuple[float, ...] = (1.0,)
        app_c: tuple[float, ...] = (0.0,)
    else:
        est, _, gain = separate(positions)
        est_nom, _, _ = separate(nominal)
        own, app = float(est[0]), float(est[1])
        own_nom, app_nom = float(est_nom[0]), float(est_nom[1])
        inputs_at = tuple(p.as_input() for p in positions)
        own_c, app_c = tuple(float(c) for c in gain[0]), tuple(float(c) for c in gain[1])
    span_h = (max(r.t_start_s for r in drift_records)
              - min(r.t_start_s for r in drift_records) + 2 * tc) / SECONDS_PER_HOUR
    w_h = (EARTH_RATE_DPH * math.cos(math.radians(latitude_deg))
           if latitude_deg is not None else None)
    inputs = AxisInputs(gyro, inputs_at, own_c, app_c, own, app, k_as_v_per_deg,
                        stated.k_as_u_rel, amplitude, stated.pulse_mismatch_max_rel,
                        shape.angle_mean, shape.angle_end, tc, pooled.offset_s,
                        pooled.offset_u_s, pooled.cycles,
                        stated.drift_random_walk_dph_per_rth, span_h,
                        stated.turn_tolerance_deg, w_h, vertical, stated.corrections)
    # every U is its budget's k(nu_eff) u_c (docs/method.md B, D1)
    b_own, b_app = own_budget(inputs), apparent_budget(inputs)
    return AxisDrift(gyro, own, b_own.U, app, b_app.U if b_app is not None else 0.0,
                     tuple(positions), tuple(cycles), pooled, own_nom, app_nom, amplitude,
                     inputs, b_own, b_app, vertical,
                     example_cycle(drift_records[0], pooled.offset_s))


@dataclass(frozen=True)
class DriftResult:
    """The drift-pulse procedure's figures (CONTRACT "The drift-pulse procedure")."""

    axes: dict[str, AxisDrift]
    latitude_deg: float
    azimuth_deg: float | None
    azimuth_u_deg: float | None
    earth_horizontal_dph: float | None         # |(app_x, app_y)|, measured
    earth_horizontal_u_dph: float | None
    budgets: tuple[Budget, ...] = ()           # of the azimuth and W_h (docs/method.md B)

    @property
    def earth_horizontal_expected_dph(self) -> float:
        """W_h = 15.041 cos(latitude) (docs/method.md B)."""
        return EARTH_RATE_DPH * math.cos(math.radians(self.latitude_deg))

    @property
    def earth_consistent(self) -> bool | None:
        """Measured W_h agrees with the latitude's within U: k_as and levelling check."""
        if self.earth_horizontal_dph is None or self.earth_horizontal_u_dph is None:
            return None
        return (abs(self.earth_horizontal_dph - self.earth_horizontal_expected_dph)
                <= self.earth_horizontal_u_dph)

    def figures(self) -> DriftFigures:
        """result.json's drift body (result.py); the platform's figures only with x and y."""
        az, wh = self.azimuth_budget, self.earth_budget
        return DriftFigures(
            axes={g: ax.figures() for g, ax in self.axes.items()},
            latitude_deg=self.latitude_deg,
            earth_horizontal_expected_dph=self.earth_horizontal_expected_dph,
            azimuth_deg=self.azimuth_deg, azimuth_u_deg=self.azimuth_u_deg,
            azimuth_U_deg=self.azimuth_u_deg, earth_horizontal_dph=self.earth_horizontal_dph,
            earth_horizontal_u_dph=self.earth_horizontal_u_dph,
            earth_horizontal_U_dph=self.earth_horizontal_u_dph,
            earth_horizontal_consistent=self.earth_consistent,
            budgets=tuple(b.record() for b in self.budgets),
            azimuth_coverage_factor=None if az is None else az.k,
            azimuth_dof_eff=UNSET if az is None else az.dof_eff,
            earth_horizontal_coverage_factor=None if wh is None else wh.k,
            earth_horizontal_dof_eff=UNSET if wh is None else wh.dof_eff)

    @property
    def azimuth_budget(self) -> Budget | None:
        return next((b for b in self.budgets if b.key == "azimuth_deg"), None)

    @property
    def earth_budget(self) -> Budget | None:
        return next((b for b in self.budgets if b.key == "earth_horizontal_dph"), None)

    def checks(self, tolerance_dph: float | None, rule: str) -> list[DriftCheck]:
        """Own drift against the tolerance under the decision rule; the Earth-rate
        consistency (k_as, levelling; docs/method.md B)."""
        out: list[DriftCheck] = []
        for g, ax in self.axes.items():
            if tolerance_dph is None:
                continue
            tol = float(tolerance_dph)
            c = judge(g, 0.0, "own_drift", ax.own_dph, ax.own_u_dph, tol, rule)
            out.append(OwnDriftCheck(axis=g, value_dph=ax.own_dph, u_dph=ax.own_u_dph,
                                     U_dph=ax.own_u_dph, tolerance_dph=tol, rule=c.rule,
                                     verdict=c.verdict, reason=c.reason,
                                     capability_ratio=c.capability_ratio,
                                     capability_ok=c.capability_ok))
        if self.earth_consistent is not None and self.earth_horizontal_dph is not None \
                and self.earth_horizontal_u_dph is not None:
            out.append(EarthRateCheck.of(self.earth_horizontal_dph,
                                         self.earth_horizontal_u_dph,
                                         self.earth_horizontal_expected_dph,
                                         self.earth_consistent))
        return out


def azimuth_deg(app_x_dph: float, app_y_dph: float, u_x_dph: float, u_y_dph: float
                ) -> tuple[float, float]:
    """A = atan2(-app_y, app_x) and its standard uncertainty for independent app_x, app_y
    (docs/method.md B), deg. The reported U is the azimuth budget's (budgets.py), which
    adds the two k_as' correlation and the one turn of the platform."""
    a = math.degrees(math.atan2(-app_y_dph, app_x_dph)) % 360.0
    r2 = app_x_dph ** 2 + app_y_dph ** 2
    # dA/dx = y / r^2, dA/dy = -x / r^2 (rad per deg/h)
    u = math.sqrt((app_y_dph * u_x_dph) ** 2 + (app_x_dph * u_y_dph) ** 2) / r2
    return a, math.degrees(u)


def analyze(records: Mapping[str, Sequence[CycleRecord]], shape: PulseShape,
            k_as_v_per_deg: Mapping[str, float], latitude_deg: float,
            stated: Mapping[str, StatedErrors] | None = None) -> DriftResult:
    """Every gyro's cycles -> own and apparent drifts, the azimuth, the Earth-rate check."""
    stated = stated or {}
    axes = {g: analyze_axis(g, recs, shape, k_as_v_per_deg[g],
                            stated.get(g, StatedErrors()), latitude_deg)
            for g, recs in records.items()}
    az = az_u = wh = wh_u = None
    budgets: tuple[Budget, ...] = ()
    if "x" in axes and "y" in axes:
        x, y = axes["x"].inputs, axes["y"].inputs
        az, _ = azimuth_deg(x.app_dph, y.app_dph, 0.0, 0.0)
        wh = math.hypot(x.app_dph, y.app_dph)
        # U = k(nu_eff) u_c of each budget, the k_as correlated (docs/method.md B, D1)
        budgets = (azimuth_budget(x, y, az), earth_budget(x, y, wh))
        az_u, wh_u = budgets[0].U, budgets[1].U
    return DriftResult(axes, latitude_deg, az, az_u, wh, wh_u, budgets)
