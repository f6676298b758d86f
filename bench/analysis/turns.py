"""Per-turn rate, rate error and rate instability from zero-mark edge times (docs/method.md A1, A2).

API
    CounterBudget(timestamp_u_s=0.0, trigger_jitter_s=0.0, timebase_limit_rel=0.0)
    period_rate_error(rate_dps, period_error_s, period_s) -> float        # docs/method.md A1
    turn_rates_dps(edge_times_s, sign) -> np.ndarray                      # one per turn
    edges_from_periods(first_edge_s, periods_s) -> np.ndarray
    analyze_turns(windows, set_rate_dps, budget) -> TurnsResult

`windows` is a sequence of edge-time arrays, one per window of whole turns at the same
commanded rate (the engine's '+w, -w, +w' order gives two '+' windows). N + 1 edges bound
N turns.

Why edge timestamps and not the counter's period readings: the mean rate over a window
is N * 360 / (t_N - t_0), so only the first and last edge's timing errors reach it; the
per-turn periods share edges, so their errors are negatively correlated and averaging N
periods does not beat the two-edge figure (docs/method.md A1; the paper's per-period error
budget dT applies to each per-turn rate, not to the mean).

U of the rate error combines: the timing of each window's two end edges, the counter's
timebase (rectangular), and a Type A repeatability term, eq. 2's relative std over
sqrt(N) with its degrees of freedom (`REPEATABILITY_FORMULA`); k is the t-factor of the
effective degrees of freedom (bench/analysis/coverage.py, docs/method.md D1): the
certificate states the table's rate error, of which these N turns are one sample, not
only how well these N turns were timed.

The counter sees |T|: the sign of every rate is the sign of the command (docs/method.md A1).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bench.analysis.coverage import expanded

FULL_TURN_DEG = 360.0
#: docs/method.md A2, rendered by the certificate's method section from here: the Type A
#: term of the rate error as `pool_type_a` and `analyze_turns` compute it
REPEATABILITY_FORMULA = ("u_rep = σ_A / √N,   ν_rep = N₊ + N₋ − 2   (σ_A = √(Σ± Σ_i (ω_i/ω_set − "
                         "mean)² / ν_rep), pooled over both directions of the pair, never "
                         "below the timing floor ΔT / T)")
#: docs/method.md A2: the rate error's combined and expanded uncertainty (k from D1)
RATE_ERROR_U_FORMULA = "u_c = √(u_timing² + u_timebase² + u_rep²);   U = k(ν_eff) · u_c"

# a per-turn rate this far from the command means a missed or doubled zero mark
_TURN_RATE_SANITY_REL = 0.1


@dataclass(frozen=True)
class CounterBudget:
    """Timing error sources of the counter chain, per edge (standard uncertainties).

    timestamp_u_s: the counter's own timestamp error per edge (resolution, interpolator,
        trigger-level noise), standard deviation, s.
    trigger_jitter_s: the slot sensor's edge-timing instability per edge, std, s (the
        paper measured a rise-time std of 27 ns, docs/method.md A1).
    timebase_limit_rel: the counter timebase's maximum relative frequency error (data
        sheet, calibration certificate); treated as a rectangular distribution.
    time_tie_u_s: how well the counter's start event sits on the FOG's time axis (the
        time tie, drivers/time_tie.py), std, s. It shifts every edge alike against the
        FOG record, so it leaves the counter's rates alone; it moves the FOG window and
        the phase of the harmonics (360 * h * u / T deg), reported beside them.
    timebase_correction_rel: a time-base offset e the analysis corrected the edges for (a
        run folder's corrections file, issue 58; 0: none applied).
    timebase_correction_u_rel: that correction's standard uncertainty (its U / 2), a Type
        B term of the rate error and of k (docs/method.md A1, "A counter's time-base
        correction"); 0 when none was applied, and then no term at all.
    """

    timestamp_u_s: float = 0.0
    trigger_jitter_s: float = 0.0
    timebase_limit_rel: float = 0.0
    time_tie_u_s: float = 0.0
    timebase_correction_rel: float = 0.0
    timebase_correction_u_rel: float = 0.0

    def __post_init__(self) -> None:
        for name in ("timestamp_u_s", "trigger_jitter_s", "timebase_limit_rel",
                     "time_tie_u_s", "timebase_correction_u_rel"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"counter budget: {name} must be finite and >= 0, got {v}")
        if not math.isfinite(self.timebase_correction_rel):
            raise ValueError("counter budget: timebase_correction_rel must be finite, got "
                             f"{self.timebase_correction_rel}")

    @property
    def edge_u_s(self) -> float:
        """Standard uncertainty of one edge's time."""
        return math.hypot(self.timestamp_u_s, self.trigger_jitter_s)

    @property
    def period_u_s(self) -> float:
        """Of one period: two independent edges (docs/method.md A1, dT per period)."""
        return math.sqrt(2.0) * self.edge_u_s

    @property
    def timebase_u_rel(self) -> float:
        return self.timebase_limit_rel / math.sqrt(3.0)

    @property
    def timebase_k_u_rel(self) -> float:
        """The time base's standard uncertainty as it enters k (eq. 5): the limit's, and
        an applied correction's beside it (docs/method.md A1, a counter's time-base
        correction: k moves by about -e k, so u(e) enters as k u(e))."""
        if self.timebase_correction_u_rel == 0.0:
            return self.timebase_u_rel          # to the bit as without the term
        return math.hypot(self.timebase_u_rel, self.timebase_correction_u_rel)


def period_rate_error(rate_dps: float, period_error_s: float, period_s: float) -> float:
    """Rate error caused by a period error dT: dw = w * dT / (T + dT) (docs/method.md A1)."""
    return rate_dps * period_error_s / (period_s + period_error_s)


def edges_from_periods(first_edge_s: float, periods_s: Sequence[float] | np.ndarray
                       ) -> np.ndarray:
    """Edge times from a gapless series of period readings (counter in period mode).

    Each reading then carries both its edges' errors, and the reconstructed edges
    accumulate them: prefer the counter's own timestamps when it has them.
    """
    p = np.asarray(periods_s, dtype=float)
    if p.ndim != 1 or p.size == 0 or not np.all(p > 0):
        raise ValueError("periods_s must be a non-empty 1-D array of positive periods")
    return float(first_edge_s) + np.concatenate(([0.0], np.cumsum(p)))


def check_edges(edge_times_s: np.ndarray, what: str) -> np.ndarray:
    """Edge times as a float array; at least one whole turn, strictly increasing."""
    e = np.asarray(edge_times_s, dtype=float)
    if e.ndim != 1 or e.size < 2:
        raise ValueError(f"{what}: need at least 2 zero-mark edges (one whole turn), "
                         f"got {e.size}")
    if not np.all(np.isfinite(e)):
        raise ValueError(f"{what}: edge times must be finite")
    if not np.all(np.diff(e) > 0):
        raise ValueError(f"{what}: edge times must be strictly increasing")
    return e


def turn_rates_dps(edge_times_s: np.ndarray, sign: int) -> np.ndarray:
    """w_i = sign * 360 / T_i (docs/method.md A1; the counter only sees |T|)."""
    return sign * FULL_TURN_DEG / np.diff(edge_times_s)


@dataclass(frozen=True)
class TurnsResult:
    """docs/method.md A1/A2 for one commanded rate (all windows of one sign)."""

    set_rate_dps: float
    turns: int
    counter_rate_dps: tuple[float, ...]
    mean_rate_dps: float               # total angle / total time over all timed turns
    rate_error_rel: float              # (mean - set) / set, signed (eq. 1, signed)
    rate_error_u_rel: float            # expanded, k = coverage_factor (docs/method.md D1)
    rate_instability_rel: float | None  # eq. 2 (None below 2 turns)
    rate_instability_floor_rel: float  # what edge timing alone adds to eq. 2
    timing_u_rel: float                # standard, from the windows' end edges
    timebase_u_rel: float              # standard, common to every rate
    budget: CounterBudget
    repeatability_u_rel: float = 0.0   # standard, Type A: sigma_A / sqrt(N)
    repeatability_basis: str = ""      # which sigma the Type A term rests on, and why
    repeatability_dof: float | None = None   # nu of the Type A term (None: no term)
    dof_eff: float | None = None       # Welch-Satterthwaite over the three terms (None: inf)
    coverage_factor: float = 2.0       # k = t_95.45(nu_eff) (docs/method.md D1)


def rate_error_u(timing_u_rel: float, timebase_u_rel: float, repeat_u_rel: float,
                 repeat_dof: float | None, correction_u_rel: float = 0.0
                 ) -> tuple[float | None, float, float]:
    """(nu_eff, k, U) of the rate error from its three standard uncertainties
    (docs/method.md A2 `RATE_ERROR_U_FORMULA`, k by D1); timing and timebase are Type B.
    An applied time-base correction's u(e) is a fourth Type B term, sensitivity 1 (docs/
    method.md A1, a counter's time-base correction: delta moves by about +e); none (0)
    leaves the sum as it was, to the bit."""
    terms = [(timing_u_rel, None), (timebase_u_rel, None), (repeat_u_rel, repeat_dof)]
    if correction_u_rel > 0.0:
        terms.append((correction_u_rel, None))
    _, nu, k, big_u = expanded(terms)
    return nu, k, big_u


def pool_type_a(results: Sequence[TurnsResult]) -> list[TurnsResult]:
    """docs/method.md A2: the Type A term of each direction of one pair from the per-turn
    scatter pooled over both (the same table at the same |rate|: one sigma in the model),
    nu = sum (N_i - 1) degrees of freedom, still never below each direction's timing floor.
    The rate error's U is recomputed with it (k from nu_eff, docs/method.md D1); each budget
    names its basis."""
    ss, nu = 0.0, 0
    for r in results:
        rel = np.asarray(r.counter_rate_dps) / abs(r.set_rate_dps)
        if rel.size >= 2:
            ss += float(np.sum((rel - rel.mean()) ** 2))
            nu += rel.size - 1
    if len(results) < 2 or nu < 2:
        return list(results)
    pooled = math.sqrt(ss / nu)
    out = []
    for r in results:
        basis_sigma = max(pooled, r.rate_instability_floor_rel)
        what = ("timing floor" if pooled < r.rate_instability_floor_rel else
                "sample sigma pooled over both directions")
        basis = (f"{what} {basis_sigma:.3g} (pooled sigma {pooled:.3g} from "
                 f"{len(results)} directions, {nu} dof)")
        rep = basis_sigma / math.sqrt(r.turns)      # docs/method.md A2: u_rep = sigma_A / sqrt(N)
        dof_eff, k, big_u = rate_error_u(r.timing_u_rel, r.timebase_u_rel, rep, float(nu),
                                         r.budget.timebase_correction_u_rel)
        out.append(dataclasses.replace(r, rate_error_u_rel=big_u, repeatability_u_rel=rep,
                                       repeatability_basis=basis,
                                       repeatability_dof=float(nu), dof_eff=dof_eff,
                                       coverage_factor=k))
    return out


def analyze_turns(windows: Sequence[np.ndarray], set_rate_dps: float,
                  budget: CounterBudget) -> TurnsResult:
    """Per-turn rates, eq. 1 (signed), eq. 2 and U (k from nu_eff, docs/method.md D1) of the
    mean rate error."""
    if not windows:
        raise ValueError("analyze_turns: no windows")
    if set_rate_dps == 0 or not math.isfinite(set_rate_dps):
        raise ValueError(f"analyze_turns: set rate must be finite and non-zero, got "
                         f"{set_rate_dps}")
    sign = 1 if set_rate_dps > 0 else -1
    edges = [check_edges(e, f"window {i}") for i, e in enumerate(windows)]
    rates = np.concatenate([turn_rates_dps(e, sign) for e in edges])
    off = np.abs(rates / set_rate_dps - 1.0)
    if np.any(off > _TURN_RATE_SANITY_REL):
        i = int(np.argmax(off))
        raise ValueError(f"turn {i}: counter rate {rates[i]:.6g} deg/s is "
                         f"{off[i] * 100:.1f} % off the set {set_rate_dps:g} deg/s: "
                         "a missed or extra zero mark?")
    n_turns = int(rates.size)
    total_s = float(sum(e[-1] - e[0] for e in edges))
    # docs/method.md A1: mean over whole turns = angle / time; only each window's end edges count
    mean = sign * FULL_TURN_DEG * n_turns / total_s
    err = (mean - set_rate_dps) / set_rate_dps
    timing_u_rel = math.sqrt(len(edges)) * budget.period_u_s / total_s
    # docs/method.md A2, eq. 2 with the square root the paper's print lost
    instab = (float(np.std(rates, ddof=1) / abs(np.mean(rates))) if n_turns >= 2 else None)
    floor = budget.period_u_s * n_turns / total_s  # dT / T per turn (docs/method.md A1)
    # Type A: the table's own turn-to-turn scatter makes the mean of N turns uncertain as
    # an estimate of the table's rate error (sigma / sqrt(N)); the timing terms only say
    # how well these particular N turns were timed. docs/method.md A2: the per-turn rates
    # scatter at least by the timing floor, so a sample sigma below it (few turns, chance)
    # is raised to the floor: the Type A term never rests on less than is known
    basis_sigma, basis = type_a_sigma(instab, floor, n_turns)
    repeat_u_rel = basis_sigma / math.sqrt(n_turns)   # docs/method.md A2: sigma_A / sqrt(N)
    repeat_dof = float(n_turns - 1) if n_turns >= 2 else None
    dof_eff, k, big_u = rate_error_u(timing_u_rel, budget.timebase_u_rel, repeat_u_rel,
                                     repeat_dof, budget.timebase_correction_u_rel)
    return TurnsResult(
        set_rate_dps=float(set_rate_dps), turns=n_turns,
        counter_rate_dps=tuple(float(r) for r in rates), mean_rate_dps=float(mean),
        rate_error_rel=float(err), rate_error_u_rel=big_u, rate_instability_rel=instab,
        rate_instability_floor_rel=float(floor), timing_u_rel=float(timing_u_rel),
        timebase_u_rel=budget.timebase_u_rel, budget=budget,
        repeatability_u_rel=float(repeat_u_rel), repeatability_basis=basis,
        repeatability_dof=repeat_dof, dof_eff=dof_eff, coverage_factor=k)


def type_a_sigma(sample_rel: float | None, floor_rel: float, n: int) -> tuple[float, str]:
    """The sigma a Type A term of N turns rests on, and the budget's words for it
    (docs/method.md A2): the sample sigma, or the timing floor when the sample falls below
    it; its n - 1 degrees of freedom give k (docs/method.md D1)."""
    if sample_rel is None:
        return 0.0, "one turn: no Type A term"
    if sample_rel < floor_rel:
        return floor_rel, (f"timing floor {floor_rel:.3g} (sample sigma {sample_rel:.3g} "
                           f"of {n} turns lies below it), {n - 1} dof")
    return sample_rel, f"sample sigma of {n} turns, {n - 1} dof"
