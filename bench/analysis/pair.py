"""docs/method.md part A for one +/- rate pair: the entry point the engine calls.

API
    analyze_pair(halves: Sequence[HalfRecord], set_rate_dps: float, *, fog_rate_hz: float,
                 counter_budget: CounterBudget = CounterBudget(), harmonics: int = 4,
                 mains_hz: float | None = 50.0, static_fog_dps: np.ndarray | None = None,
                 fine_bin_deg: float = 1.0, binned_deg: float = 1.0,
                 averaging_deg: Sequence[float] = (1.0, 10.0, 360.0),
                 floor_samples: int = 1 << 20, chunk: int = DEFAULT_CHUNK) -> PairAnalysis

`halves` in the order they ran (the engine's default '+w, -w, +w'); each HalfRecord has
the sign of its command, the N + 1 zero-mark edge times bounding its timed turns, and the
FOG samples (they may extend past the turns). `set_rate_dps` is the magnitude. `static_fog_dps`: a record of the same FOG at rest, at
fog_rate_hz, for the noise floor of docs/method.md A5 (without it, the pair's own residual
gives the floor, and `floor_source` says so). `floor_samples`: how many samples per
direction that own-data floor is estimated from. Raises ValueError, naming the half,
for inputs that cannot give an honest result (FOG not covering the turns, a turn without
samples, non-finite samples, a missed zero mark, one sign only, mains above Nyquist).

Result: `PairAnalysis.rates` = (the '+' RateResult, the '-' RateResult), `.pair` the
PairResult (procedures/rate_ladder/result.py lays each out as its result.json entry,
CONTRACT §3).

Steps (each in its module):
 1. window.py   exact FOG integrals over each half's whole turns;
 2. turns.py    A1/A2 per direction from the edges;
 3. crosscal.py a provisional k, w0, drift from the per-turn means (for the angles);
 4. sums.py     one pass over the samples per half: angle, design rows, Gram, bin sums;
 5. systematic.py the harmonic + mains fit per direction; noise inflation over the pair;
 6. crosscal.py A3 from the half means, their uncertainty from the fit's residual;
 7. systematic.py, random_part.py: A4 and A5 with the final calibration.

Cost: two reads of the FOG record (the integrals, then the pass) plus a subset for the
noise floor; memory: a few chunk-sized buffers, whatever the record's length.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import TypedDict, Unpack

import numpy as np

from bench.analysis.crosscal import (
    CrossCalibration,
    DriftEstimate,
    HalfMean,
    cross_calibrate,
    fit_turns,
)
from bench.analysis.random_part import floor_from_fit, floor_from_static, random_part
from bench.analysis.results import PairAnalysis, PairResult, RateResult, SystematicResult
from bench.analysis.sums import Design, accumulate
from bench.analysis.systematic import (
    DirectionFit,
    NoiseInflation,
    binned_systematic,
    detection_dict,
    detection_threshold,
    harmonic_block_deg,
    harmonics_result,
    long_block_deg,
    mains_result,
    noise_inflation,
    solve_direction,
    tone_interval,
)
from bench.analysis.turns import (
    FULL_TURN_DEG,
    CounterBudget,
    analyze_turns,
    pool_type_a,
    turn_rates_dps,
)
from bench.analysis.window import DEFAULT_CHUNK, HalfRecord, Window

_RATE_MATCH_REL = 1e-3


def _check_rate(windows: Sequence[Window], fog_rate_hz: float, mains_hz: float | None) -> None:
    if not fog_rate_hz > 0:
        raise ValueError(f"fog_rate_hz must be > 0, got {fog_rate_hz}")
    for w in windows:
        if w.uniform_dt_s is not None and abs(w.uniform_dt_s * fog_rate_hz - 1) > _RATE_MATCH_REL:
            raise ValueError(f"half {w.index}: FOG sample times say "
                             f"{1 / w.uniform_dt_s:.6g} Hz, fog_rate_hz says {fog_rate_hz:g}")
    if mains_hz is not None and 2 * mains_hz >= fog_rate_hz:
        raise ValueError(f"mains_hz {mains_hz:g} is at or above the FOG's Nyquist frequency "
                         f"({fog_rate_hz / 2:g} Hz): set mains_hz to None")


def _turn_table(windows: Sequence[Window]) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                     np.ndarray]:
    """Per-turn FOG means, counter rates, centre times and sample counts, all halves."""
    f = np.concatenate([w.turn_fog_mean_dps for w in windows])
    c = np.concatenate([turn_rates_dps(w.edges_s, w.sign) for w in windows])
    t = np.concatenate([w.turn_centres_s for w in windows])
    n = np.concatenate([w.turn_samples for w in windows]).astype(float)
    return f, c, t, n


def _half_means(fits: dict[int, DirectionFit], inflation_factor: float,
                budget: CounterBudget, keep: set[int]) -> list[HalfMean]:
    out = []
    for fit in fits.values():
        for ws in fit.sums:
            win = ws.win
            if win.index not in keep:
                continue
            c = win.sign * FULL_TURN_DEG * win.turns / win.duration_s
            out.append(HalfMean(
                sign=win.sign, fog_mean_dps=win.fog_mean_dps,
                # white: sigma / sqrt(n); coloured: the block-sum check scales it up
                fog_mean_u_dps=fit.sigma_dps * math.sqrt(inflation_factor / ws.n),
                counter_mean_dps=c,
                counter_mean_u_dps=abs(c) * budget.period_u_s / win.duration_s,
                t_centre_s=win.t_centre_s, turns=win.turns))
    return sorted(out, key=lambda h: h.t_centre_s)


def _anchor_session(halves: Sequence[HalfRecord]) -> int | None:
    """The session whose halves calibrate the FOG when a pair spans sessions, else None.

    Each session (a run, a --resume) has its own time axis and the FOG its own bias
    (re-powered, re-warmed): halves of different sessions share k but not w0 or the
    drift. k, w0 and the drift come from the one session that holds both signs (the one
    with the most turns, the later on a tie); the other halves still give their turns
    (rate error, instability) and their intra-turn content (each window has its own
    constant and slope in the systematic fit). docs/resume.md states the rule.
    """
    sessions = {h.session for h in halves}
    if len(sessions) == 1:
        return None
    both = [s for s in sessions if {h.sign for h in halves if h.session == s} == {1, -1}]
    if not both:
        raise ValueError(f"the pair's halves come from sessions {sorted(sessions)} and no "
                         "session holds both signs: k cannot be told from the per-session "
                         "FOG bias; re-acquire the pair")
    turns = {s: sum(h.edge_times_s.size - 1 for h in halves if h.session == s) for s in both}
    return max(both, key=lambda s: (turns[s], s))


def analyze_pair(halves: Sequence[HalfRecord], set_rate_dps: float, *, fog_rate_hz: float,
                 counter_budget: CounterBudget | None = None, harmonics: int = 4,
                 mains_hz: float | None = 50.0, static_fog_dps: np.ndarray | None = None,
                 fine_bin_deg: float = 1.0, binned_deg: float = 1.0,
                 averaging_deg: Sequence[float] = (1.0, 10.0, 360.0),
                 floor_samples: int = 1 << 20, chunk: int = DEFAULT_CHUNK) -> PairAnalysis:
    """docs/method.md A1-A5 for one +/- pair (see the module docstring)."""
    budget = counter_budget or CounterBudget()
    w_set = abs(float(set_rate_dps))
    if not (w_set > 0 and math.isfinite(w_set)):
        raise ValueError(f"set_rate_dps must be finite and non-zero, got {set_rate_dps}")
    if len(halves) < 2:
        raise ValueError(f"a pair needs at least two halves (+w and -w), got {len(halves)}")
    design = Design(harmonics=harmonics, mains_hz=mains_hz, fine_bin_deg=fine_bin_deg)
    windows = [Window.from_record(h, i, chunk) for i, h in enumerate(halves)]
    _check_rate(windows, fog_rate_hz, mains_hz)
    signs = sorted({w.sign for w in windows}, reverse=True)
    if signs != [1, -1]:
        raise ValueError("a pair needs halves of both signs")

    # docs/method.md A2: the Type A term pooled over both directions of the pair
    turns = dict(zip(signs, pool_type_a([analyze_turns([w.edges_s for w in windows
                                                        if w.sign == s], s * w_set, budget)
                                         for s in signs]), strict=True))
    anchor = _anchor_session(halves)
    # the windows that calibrate the FOG: all, or those of the anchor session
    cal_windows = [w for w, h in zip(windows, halves, strict=True)
                   if anchor is None or h.session == anchor]

    # provisional calibration from per-turn means: only the angles depend on it, weakly
    f, c, t, n = _turn_table(cal_windows)
    provisional = fit_turns(f, c, t, n).calibration()

    by_sign = {s: [accumulate(w, provisional, design, chunk) for w in windows if w.sign == s]
               for s in signs}
    fits = {s: solve_direction(by_sign[s]) for s in signs}
    total_turns = sum(w.turns for w in windows)
    infl_harm = noise_inflation(list(fits.values()), harmonic_block_deg(design))
    infl_long = noise_inflation(list(fits.values()), long_block_deg(design, total_turns))

    drift = _within_half_drift(fits, infl_long.factor, cal_windows, (f, c, t), budget)

    cal_index = {w.index for w in cal_windows}
    halves_mean = _half_means(fits, infl_long.factor, budget, cal_index)
    xcal = cross_calibrate(halves_mean, drift=drift, timebase_u_rel=budget.timebase_k_u_rel)
    final = xcal.calibration()
    k_u_std = xcal.k_u / 2.0

    floor = (floor_from_static(static_fog_dps) if static_fog_dps is not None else None)
    rates = []
    for s in signs:
        fit = fits[s]
        set_signed = s * w_set
        sysres = SystematicResult(
            harmonics=harmonics_result(fit, final.k, k_u_std, set_signed, infl_harm),
            mains=mains_result(fit, final.k, k_u_std, infl_harm),
            binned=binned_systematic(fit, final, set_signed, binned_deg, infl_harm),
            residual_std_dps=fit.sigma_dps / abs(final.k), inflation=infl_harm,
            detection=detection_dict(design))
        fl = floor if floor is not None else floor_from_fit(fit, floor_samples)
        rnd = random_part(fit, final, set_signed, fl, fog_rate_hz, averaging_deg,
                          own_bias=frozenset(range(len(windows))) - cal_index)
        rates.append(RateResult(turns_result=turns[s], systematic=sysres, random=rnd,
                                windows=_windows_result(fit, halves)))
    return PairAnalysis(rates=tuple(rates),
                        pair=_pair_result(halves, anchor, w_set, xcal, infl_long))


def _within_half_drift(fits: dict[int, DirectionFit], inflation_factor: float,
                       cal_windows: Sequence[Window],
                       turn_table: tuple[np.ndarray, np.ndarray, np.ndarray],
                       budget: CounterBudget) -> DriftEstimate | None:
    """The FOG's drift within the halves (docs/method.md A3): the slope of the per-turn
    means of the calibrating windows, each weighted by its honest variance (the fit's
    sigma inflated for coloured noise over the turn's samples, plus the counter's period
    uncertainty). None when the slope's uncertainty is not finite (too few turns)."""
    f, c, t = turn_table
    sig2 = {s: fit.sigma_dps ** 2 * inflation_factor for s, fit in fits.items()}
    var_turn = np.concatenate([np.full(w.turns, sig2[w.sign]) / w.turn_samples
                               for w in cal_windows])
    var_turn += (c * budget.period_u_s / np.concatenate([w.turn_periods_s
                                                           for w in cal_windows])) ** 2
    tf = fit_turns(f, c, t, 1.0 / var_turn)
    return (DriftEstimate(tf.drift_dps_per_s, tf.drift_u_dps_per_s,
                          "slope of the per-turn FOG means within the halves")
            if math.isfinite(tf.drift_u_dps_per_s) else None)


def _windows_result(fit: DirectionFit, halves: Sequence[HalfRecord]
                    ) -> tuple[dict[str, float | int], ...]:
    """The halves one direction's fit used, as result.json lists them under the rate."""
    return tuple({"half": ws.win.index, "turns": ws.win.turns,
                  "t_start_s": float(ws.win.edges_s[0]),
                  "t_end_s": float(ws.win.edges_s[-1]), "samples": ws.n,
                  "session": halves[ws.win.index].session}
                 for ws in fit.sums)


def _pair_result(halves: Sequence[HalfRecord], anchor: int | None, w_set: float,
                 xcal: CrossCalibration, infl_long: NoiseInflation) -> PairResult:
    """The pair's calibration, with the bias model stated when its halves span sessions
    (_anchor_session: k, w0 and the drift from the anchor session's halves only)."""
    sessions = tuple(h.session for h in halves)
    if anchor is None:
        return PairResult(rate_dps=w_set, cal=xcal, noise_inflation=infl_long,
                          sessions=sessions)
    others = [str(i + 1) for i, h in enumerate(halves) if h.session != anchor]
    return PairResult(
        rate_dps=w_set, cal=xcal, noise_inflation=infl_long, sessions=sessions,
        bias_model=(f"per session: the pair spans sessions {sorted(set(sessions))}; "
                    f"k, w0 and the drift (and their U) from session {anchor}'s halves "
                    f"only; half {', '.join(others)} from another session, with a FOG "
                    "bias and drift of its own, enter the turns and the intra-turn fit "
                    "but not k"))


class PairOptions(TypedDict, total=False):
    """`analyze_pair`'s options that `analyze_pair_mains` passes on as they are."""

    counter_budget: CounterBudget | None
    harmonics: int
    static_fog_dps: np.ndarray | None
    fine_bin_deg: float
    binned_deg: float
    averaging_deg: Sequence[float]
    floor_samples: int
    chunk: int


def analyze_pair_mains(halves: Sequence[HalfRecord], set_rate_dps: float, *,
                       fog_rate_hz: float, candidates_hz: Sequence[float], source: str,
                       **kwargs: Unpack[PairOptions]) -> PairAnalysis:
    """analyze_pair with the mains frequency stated (one candidate) or found from the data
    (docs/method.md A4): every candidate below the FOG's Nyquist frequency is fitted and the
    one whose tone is the more significant over both directions is kept; its detection
    counts the candidates tried as tests too, so the false-alarm rate stays as stated.
    `systematic.mains.source` says where the frequency came from."""
    usable = [float(m) for m in candidates_hz if 2 * m < fog_rate_hz]
    if not usable:
        return analyze_pair(halves, set_rate_dps, fog_rate_hz=fog_rate_hz, mains_hz=None,
                            **kwargs)
    best, best_q = None, -math.inf
    for mains in usable:
        pa = analyze_pair(halves, set_rate_dps, fog_rate_hz=fog_rate_hz, mains_hz=mains,
                          **kwargs)
        q = sum(r.systematic.mains.significance for r in pa.rates
                if r.systematic.mains is not None)
        if best is None or q > best_q:
            best, best_q = pa, q
    assert best is not None
    if len(usable) > 1:
        source = (f"{source}: {best.rates[0].systematic.mains.frequency_hz:g} Hz of "
                  f"{', '.join(f'{m:g}' for m in usable)} (chi2 over both directions "
                  f"{best_q:.3g})" if best.rates[0].systematic.mains else source)
    return _with_mains_source(best, source, searched=len(usable))


def _with_mains_source(pa: PairAnalysis, source: str, searched: int) -> PairAnalysis:
    """The pair's mains results with where their frequency came from; a tone picked among
    `searched` candidates is detected against a threshold that counts them as tests."""
    rates = []
    for r in pa.rates:
        m = r.systematic.mains
        if m is not None:
            tests = int(r.systematic.detection.get("tones_tested", 1)) + searched - 1
            threshold = detection_threshold(tests)
            # docs/method.md A4, D2: the interval a +/- c u(a) with c for `tests` tones
            detected, upper, c = tone_interval(m.amplitude_dps, m.amplitude_u_dps / 2.0, tests)
            m = dataclasses.replace(m, source=source, detected=detected,
                                    amplitude_upper_dps=upper, interval_factor=c)
            r = dataclasses.replace(r, systematic=dataclasses.replace(
                r.systematic, mains=m, detection={**r.systematic.detection,
                                                  "tones_tested": tests,
                                                  "chi2_threshold": threshold}))
        rates.append(r)
    return PairAnalysis(rates=tuple(rates), pair=pa.pair)
