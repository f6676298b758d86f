"""The rate ladder's uncertainty budgets (EA-4/02 form, bench.report.budget), built from the
analysis results in result.json and added to it (`budgets` lists; additions only):

- per rate: the rate error delta (eq. 1), the raw intra-turn instability (docs/method.md
  A5), each harmonic's and the mains tone's amplitude and phase (A4);
- per +/- pair: the FOG's scale k, bias w0 and bias drift (A3, eq. 5-6), propagated through the
  weighted least-squares fit of the halves' FOG means on the counter's means (the same
  model the analysis fits: a bias and, with three or more halves, a linear drift).

The analysis (bench/analysis, procedures/rate_ladder/analysis.py) decides the values and
their U; this module only lays out where each U comes from.
"""

from __future__ import annotations

import msgspec
import numpy as np

from bench.report.budget import (
    CHI_SQUARE,
    NORMAL,
    RECTANGULAR,
    STUDENT_T,
    Budget,
    BudgetRecord,
    Term,
    num,
)
from procedures.rate_ladder.result import Half, LadderAxis, NoiseFloor, PairEntry, RateEntry


def _half_u(x: object) -> float | None:
    """A standard uncertainty from an expanded one (k = 2, CONTRACT: _U_/_u_)."""
    v = num(x)
    return None if v is None else v / 2.0


def rate_error_budget(r: RateEntry) -> Budget | None:
    """delta = mean(per-turn rates)/set - 1 (eq. 1): repeatability of the turns (Type A),
    the counter's time-stamping and the time base (Type B)."""
    b = r.rate_error_budget
    if b is None:
        return None
    turns = r.turns or 0
    terms = []
    rep = num(b.repeatability_ustd_rel)
    # docs/method.md A2: nu of the Type A term as the analysis took it (pooled: N+ + N- - 2)
    rep_dof = num(b.repeatability_dof)
    if rep_dof is None and turns > 1:
        rep_dof = float(turns - 1)
    if rep is not None:
        terms.append(Term("mean of the per-turn rate errors (repeatability, Type A): "
                          + str(b.repeatability_basis or "sample sigma / √N"),
                          num(r.rate_error_rel), rep, STUDENT_T, 1.0, rep_dof, "1"))
    timing = num(b.timing_ustd_rel)
    if timing is not None:
        terms.append(Term("turn period timing: zero-mark edges and time tie (Type B)", 0.0,
                          timing, NORMAL, 1.0, None, "1"))
    base = num(b.timebase_ustd_rel)
    if base is not None:
        terms.append(Term(f"counter time base, limit {num(b.timebase_limit_rel)} "
                          "(Type B)", 0.0, base, RECTANGULAR, 1.0, None, "1"))
    corr_u = num(b.timebase_correction_ustd_rel)
    if corr_u is not None:
        # docs/method.md A1, a counter's time-base correction: the edges divided by 1 + e
        # move delta by e (1 + delta), about +e: sensitivity 1 to first order, as the
        # analysis combines it (bench/analysis/turns.py rate_error_u)
        terms.append(Term("counter time-base correction e applied, its as-found value "
                          "(Type B, from its calibration's U, k = 2)",
                          num(b.timebase_correction_rel), corr_u, NORMAL, 1.0, None,
                          "1"))
    if not terms:
        return None
    return Budget("rate error δ (relative)", "rate_error_rel", "1",
                  num(r.rate_error_rel), tuple(terms), num(r.rate_error_U_rel))


def _scale_term(pair: PairEntry | None, value: float | None) -> list[Term]:
    """The FOG's scale k converts its rates to the table's: a relative value read through
    the FOG scales as 1/k (sensitivity -value/k)."""
    if pair is None or value is None:
        return []
    k, uk = num(pair.k), _half_u(pair.k_U)
    if not k or uk is None:
        return []
    return [Term("FOG scale k from the cross-calibration (eq. 5)", k, uk, NORMAL,
                 -value / k, None, "1")]


def harmonic_budgets(r: RateEntry, pair: PairEntry | None) -> list[Budget]:
    samples = num(r.intra.samples)
    out = []
    harmonics = r.harmonics
    dof = samples - (2 * len(harmonics) + 1) if samples else None
    for h in harmonics:
        order = int(num(h.order) or 0)
        a, ua = num(h.amplitude_rel), _half_u(h.amplitude_U_rel)
        if a is not None and ua is not None:
            out.append(Budget(
                f"harmonic {order} amplitude a{order} (relative)",
                f"systematic.harmonics[{order - 1}].amplitude_rel", "1", a,
                (Term("least-squares fit of the FOG record over whole turns (Type A)", a,
                      ua, STUDENT_T, 1.0, dof, "1"), *_scale_term(pair, a)),
                2 * ua))
        p, up = num(h.phase_deg), _half_u(h.phase_U_deg)
        if p is not None and up is not None:
            out.append(Budget(
                f"harmonic {order} phase p{order}", f"systematic.harmonics[{order - 1}].phase_deg",
                "deg", p,
                (Term("least-squares fit of the FOG record over whole turns (Type A)", p,
                      up, STUDENT_T, 1.0, dof, "deg"),
                 *([Term("FOG scale k (a scale does not move a phase)",
                         num(pair.k), _half_u(pair.k_U) or 0.0, NORMAL, 0.0,
                         None, "1")] if pair and num(pair.k) else [])),
                2 * up,
                note="" if h.detected is not False else "harmonic not detected: its phase is "
                                                        "undetermined"))
    return out


def mains_budgets(r: RateEntry, pair: PairEntry | None) -> list[Budget]:
    """The mains tone's amplitude (deg/s of table rate) and phase (docs/method.md A4): the
    least-squares fit of the FOG record (Type A) and the FOG scale k it is divided by."""
    m = r.mains
    if m is None:
        return []
    samples = num(r.intra.samples)
    dof = samples - (2 * len(r.harmonics) + 3) if samples else None
    out = []
    a, ua = num(m.amplitude_dps), _half_u(m.amplitude_u_dps)
    if a is not None and ua is not None:
        out.append(Budget(
            "mains ripple amplitude (deg/s)", "systematic.mains.amplitude_dps", "deg/s", a,
            (Term("least-squares fit of the FOG record over whole turns (Type A)", a, ua,
                  STUDENT_T, 1.0, dof, "deg/s"), *_scale_term(pair, a)),
            2 * ua))
    p, up = num(m.phase_deg), _half_u(m.phase_u_deg)
    if p is not None and up is not None:
        out.append(Budget(
            "mains ripple phase", "systematic.mains.phase_deg", "deg", p,
            (Term("least-squares fit of the FOG record over whole turns (Type A)", p, up,
                  STUDENT_T, 1.0, dof, "deg"),),
            2 * up,
            note="" if m.detected is not False else "mains tone not detected: its phase is "
                                                    "undetermined"))
    return out


def intra_turn_budgets(r: RateEntry, pair: PairEntry | None,
                       floor: NoiseFloor | None) -> list[Budget]:
    """sigma_raw (A5), relative to |set|: the standard deviation of the random part (Type A,
    chi-square) and the FOG scale it is read through."""
    intra = r.intra
    raw = num(r.intra_turn_instability_rel)
    u_raw = _half_u(r.intra_turn_instability_U_rel)
    n = num(intra.samples)
    if raw is None or u_raw is None:
        return []
    out = [Budget("intra-turn instability σ, raw (relative)", "intra_turn_instability_rel",
                  "1", raw, (Term("standard deviation of the random part of the FOG rate "
                                  "(Type A)", raw, u_raw, CHI_SQUARE, 1.0,
                                  n - 1 if n else None, "1"), *_scale_term(pair, raw)),
                  2 * u_raw)]
    # the floor-corrected figure has no linear budget: near zero the propagation fails, and
    # its interval is the JCGM 101 Monte Carlo of A5 (inputs raw, nu_raw, floor, nu_floor in
    # result.json's intra_turn and the certificate's note), not k u_c
    return out


def _half_row(h: Half) -> tuple[float, float, float, float, float, int, float | None] | None:
    """A half's counter mean, FOG mean, their standard uncertainties (FOG's first), time
    centre, turns and sign; None when one of the five numbers is missing."""
    c, f, uf, uc, t = (num(x) for x in (h.counter_mean_dps, h.fog_mean_dps,
                                        h.fog_mean_ustd_dps, h.counter_mean_ustd_dps,
                                        h.t_centre_s))
    if c is None or f is None or uf is None or uc is None or t is None:
        return None
    return c, f, uf, uc, t, int(num(h.turns) or 0), h.sign


def pair_budgets(pair: PairEntry) -> list[Budget]:
    """k and w0 as the weighted least-squares fit of F_i = k C_i + w0 (+ d (t_i - t_ref))
    over the pair's halves (eq. 5-6); c_i = dk/dF_i from the fit's gain matrix, and
    dk/dC_i = -k dk/dF_i (a counter mean moves the fit as a FOG mean of -k times it)."""
    halves = pair.halves
    rows = [row for h in halves if (row := _half_row(h)) is not None]
    if len(rows) < 2 or len(rows) < len(halves):
        return []
    t_ref = num(pair.w0_t_ref_s) or 0.0
    drift = "drift" in (pair.method or "") and len(rows) >= 3
    a = np.array([[c, 1.0, *(((t - t_ref) / 3600.0,) if drift else ())]
                  for c, _, _, _, t, _, _ in rows])
    # the halves' FOG means carry the noise inflation already (bench/analysis/pair.py)
    w = np.diag([1.0 / u ** 2 for _, _, u, _, _, _, _ in rows])
    gain = np.linalg.solve(a.T @ w @ a, a.T @ w)          # beta = gain @ F
    beta = gain @ np.array([f for _, f, _, _, _, _, _ in rows])
    out = []
    # docs/method.md A3: the fit's third parameter (the column (t - t_ref) / 3600 s) is
    # the FOG's bias drift in deg/s per hour
    fitted = (("FOG scale k (eq. 5)", "k", "1", pair.k, pair.k_U),
              ("FOG bias ω0 (eq. 6)", "w0_dps", "deg/s", pair.w0_dps, pair.w0_U_dps),
              *((("FOG bias drift during the pair (A3)", "drift_dps_per_h", "deg/s/h",
                  pair.drift_dps_per_h, pair.drift_u_dps_per_h),) if drift else ()))
    for idx, (name, key, unit, value, reported) in enumerate(fitted):
        terms = []
        for i, (c, f, uf, uc, _t, turns, sign) in enumerate(rows):
            s = "+" if (num(sign) or 0) > 0 else "−"
            terms.append(Term(f"FOG mean rate, half {i + 1} ({s}) (Type A)", f,
                              uf, NORMAL, float(gain[idx, i]), None, "deg/s"))
            terms.append(Term(f"counter mean rate, half {i + 1} ({s}) (Type A)", c, uc,
                              STUDENT_T, float(-beta[0] * gain[idx, i]),
                              float(turns - 1) if turns > 1 else None, "deg/s"))
        out.append(Budget(name, key, unit, num(value), tuple(terms), num(reported),
                          note=pair.bias_model if drift else ""))
    return out


def with_budgets(axis: LadderAxis) -> LadderAxis:
    """An axis with a `budgets` list on every rate and pair: a rate is given the pair at its
    rate and the axis's noise floor."""
    def of_rate(r: RateEntry) -> tuple[BudgetRecord, ...]:
        pair = next((p for p in axis.pairs if p.rate_dps == abs(r.set_rate_dps)), None)
        return _records([b for b in (rate_error_budget(r),) if b is not None]
                        + intra_turn_budgets(r, pair, axis.noise_floor)
                        + harmonic_budgets(r, pair) + mains_budgets(r, pair))

    return msgspec.structs.replace(
        axis, rates=tuple(msgspec.structs.replace(r, budgets=of_rate(r)) for r in axis.rates),
        pairs=tuple(msgspec.structs.replace(p, budgets=_records(pair_budgets(p)))
                    for p in axis.pairs))


def _records(budgets: list[Budget]) -> tuple[BudgetRecord, ...]:
    return tuple(b.record() for b in budgets)
