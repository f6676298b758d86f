"""The rate ladder's part of the DCC (docs/method.md part A): per axis, per commanded rate
the per-turn error and instability, the per-turn rates as a list, the intra-turn
instability, the fitted harmonics and mains ripple; per +/- pair the FOG's k and w0.
`LadderDcc` answers the DCC writer's questions (bench.report.dcc.parts.DccParts).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from lxml import etree

from bench.report.certificate import methods
from bench.report.certificate.parts import Sources
from bench.report.certificate.rounding import is_resolved
from bench.report.dcc import units as U
from bench.report.dcc import vocab as V
from bench.report.dcc.conformity import Checks, judge
from bench.report.dcc.parts import DccParts
from bench.report.dcc.xml import (
    COVERAGE_PROBABILITY,
    NOT_RECORDED,
    Interval,
    budget_list,
    el,
    ident,
    list_quantity,
    name,
    num,
    quantity,
    rate_token,
    text_el,
)
from procedures.rate_ladder.codec import ladder_model
from procedures.rate_ladder.result import UNSIGNED, PairEntry, RateEntry, RateErrorBudget
from procedures.rate_ladder.result import Averaged as AveragedFigures

# the ladder's refTypes, namespace "ratebench" (docs/dcc.md, section "refTypes")
SET_RATE = V.RB + "setRate"
TURNS = V.RB + "turns"
RATE_ERROR = V.RB + "rateError"
RATE_INSTABILITY = V.RB + "rateInstability"
TIMING_FLOOR = V.RB + "timingFloor"
INTRA_TURN = V.RB + "intraTurnInstability"
INTRA_TURN_CORRECTED = V.RB + "intraTurnInstabilityCorrected"
INTRA_TURN_UPPER = V.RB + "intraTurnInstabilityUpperLimit"
FOG_FLOOR = V.RB + "fogNoiseFloor"
AVERAGED = V.RB + "averagedInstability"
WINDOW = V.RB + "averagingWindow"
PER_TURN = V.RB + "perTurnRate"
HARMONIC = V.RB + "harmonic"
HARMONIC_ORDER = V.RB + "harmonicOrder"
AMPLITUDE = V.RB + "amplitude"
PHASE = V.RB + "phase"
FREQUENCY = V.RB + "frequency"
MAINS = V.RB + "mainsRipple"
PAIR = V.RB + "crossCalibrationPair"
FOG_SCALE = V.RB + "fogScale"
FOG_BIAS = V.RB + "fogBias"
FOG_BIAS_DRIFT = V.RB + "fogBiasDrift"

#: the sections of docs/method.md the ladder follows
METHOD_SECTIONS = ("A1", "A2", "A3", "A4", "A5", "A6", "D1", "D2")
#: docs/method.md D2: the one-sided level of a '< L' limit from a 95 % interval's upper end
ONE_SIDED_P = 0.975


def two_sided(value: float, lower: float, upper: float, distribution: str, ustd: float,
              probability: float = 0.95) -> Interval:
    """A resolved magnitude's asymmetric interval (docs/method.md D2), with the standard
    uncertainty D-SI asks beside it: the figure's own (its budget's u_c, or the Monte
    Carlo's standard deviation), never a width over 4."""
    return Interval(lower, upper, probability, ustd, distribution)


def limit_interval(limit: float, distribution: str, ustd: float,
                   probability: float = ONE_SIDED_P) -> Interval:
    """'< L' (docs/method.md D2) as the interval [0, L] at its one-sided level, with the
    figure's own standard uncertainty (its budget's u_c)."""
    return Interval(0.0, limit, probability, ustd, distribution)


def _budget_ustd(r: RateEntry, key: str) -> float | None:
    """u_c of the budget of `key` on this rate (docs/method.md D1), None without one."""
    b = r.budget(key)
    return None if b is None else b.ustd


def _stated_or(x: float | None, older: float) -> float:
    """The standard uncertainty result.json states; an older result without it gets the
    interval's width over 4, as such results were written."""
    return older if x is None or not math.isfinite(x) else x


class LadderDcc(DccParts):
    """The rate ladder's answers to the DCC (the kind's `dcc` part)."""

    def dcc_item(self, src: Sources) -> tuple[str, Sequence[str]]:
        return "rotary rate table", list(src.model(ladder_model).axes)

    def dcc_used_methods(self, src: Sources) -> tuple[str, Sequence[str]]:
        return methods.A_REFERENCE, METHOD_SECTIONS

    def dcc_results(self, results: etree._Element, src: Sources, checks: Checks) -> None:
        ladder_results(results, src, checks)


def ladder_results(results: etree._Element, src: Sources, checks: Checks) -> None:
    for axis, ax in src.model(ladder_model).axes.items():
        mr = el(results, "measurementResult", id=ident("axis", axis), ref_id="item")
        name(mr, f"Axis {axis}: per-turn rate, FOG cross-calibration and intra-turn "
                 "instability (rate ladder)")
        text_el(mr, "description", "Per commanded rate and direction (signed: + is the "
                "table's positive sense). Relative values are plain fractions of the "
                "commanded rate (unit \\one).")
        res = el(mr, "results")
        for i, rate in enumerate(ax.rates):
            _rate_result(res, axis, i, rate, checks)
        for i, pair in enumerate(ax.pairs):
            _pair_result(res, axis, i, pair)
        floor = ax.noise_floor
        sd = num(floor.sample_std_dps) if floor is not None else None
        if floor is not None and sd is not None:
            r = el(res, "result", id=ident("floor", axis), ref_type=FOG_FLOOR)
            name(r, f"Axis {axis}: FOG noise floor at rest (docs/method.md A5)")
            text_el(r, "description", f"{floor.source or 'record at rest'}; "
                    f"{_or_not_recorded(floor.samples)} samples over "
                    f"{_or_not_recorded(floor.duration_s)} s.")
            quantity(el(r, "data"), ident("q", axis, "floor_std"), "standard deviation of "
                     "one FOG sample at rest", FOG_FLOOR, sd, U.DEG_PER_S,
                     label=f"axes.{axis}.noise_floor.sample_std_dps")
        if not len(res):
            r = el(res, "result")
            name(r, f"Axis {axis}: no results")
            text_el(el(r, "data"), "text", "Nothing was measured to completion on this axis.")


def _per_turn_u(b: RateErrorBudget | None, rates: list[float]) -> list[float] | None:
    """U (k = 2) of each per-turn rate, docs/method.md A1: dw/w = dT/T with T = 360/|w|, combined
    with the counter timebase: U = 2 |w| sqrt((u_T |w| / 360)^2 + u_tb^2)."""
    if b is None or num(b.period_u_s) is None:
        return None
    u_t, u_tb = num(b.period_u_s) or 0.0, num(b.timebase_u_rel) or 0.0
    return [2 * abs(w) * ((u_t * abs(w) / 360.0) ** 2 + u_tb ** 2) ** 0.5 for w in rates]


@dataclass(frozen=True)
class _Quantities:
    """Where one rate's quantities go: its result's data, their ids and result.json
    labels, and the checks each is judged by."""

    data: etree._Element
    rid: str
    path: str
    axis: str
    w_set: float | None
    checks: Checks

    def q(self, key: str, title: str, ref: str, unit: str, value: float | None,
          u: float | None = None, u_stated: bool = False, note: str | None = None,
          check: str | None = None, label: str | None = None, k: float | None = None,
          interval: Interval | None = None) -> etree._Element | None:
        """One quantity; `u_stated`: result.json should carry its U (say so when not)."""
        v = value
        if v is None:
            return None
        uu = u
        if uu is None and u_stated and interval is None:
            note = (note + " " if note else "") + "U not stated in result.json."
        node = quantity(self.data, ident(self.rid, key), title, ref, v, unit, uu,
                        label=label or f"{self.path}.{key}", note=note, k=k, interval=interval)
        if check:
            judge(node, self.checks.take(self.axis, self.w_set, check), unit,
                  magnitude=check in UNSIGNED)
        return node


def _rate_result(res: etree._Element, axis: str, i: int, r: RateEntry,
                 checks: Checks) -> None:
    """One commanded rate and direction: its per-turn figures (A1-A2), its intra-turn
    figures (A5), the rate error's budget, the averaged random part and the fitted
    systematic component (A4)."""
    w_set = num(r.set_rate_dps)
    tok = rate_token(w_set)
    path = f"axes.{axis}.rates[{i}]"
    rid = ident("r", axis, tok)
    result = el(res, "result", id=rid, ref_type=V.MEASURED)
    name(result, f"Axis {axis}, set rate {w_set:+g} deg/s" if w_set is not None
         else f"Axis {axis}, rate {i + 1}")
    verdict = r.verdict
    if verdict:
        text_el(result, "description", f"Verdict at this rate: {str(verdict).upper()}.")
    data = el(result, "data")
    qs = _Quantities(data, rid, path, axis, w_set, checks)
    eb = r.rate_error_budget
    ek = num(eb.coverage_factor) if eb is not None else None      # docs/method.md D1: k = t_95.45(nu_eff)
    _per_turn(qs, r, ek)
    _intra_turn(qs, r)
    budget_list(data, ident(rid, "budget"),
                "uncertainty budget of the rate error: standard uncertainties (k = 1) relative "
                f"to |set|; U = k sqrt(sum u^2), k = {ek or 2.0:.2f} = t_95.45(nu_eff) "
                "(docs/method.md A1-A2, D1)",
                eb, f"{path}.rate_error_budget",
                (("timing_u_rel", "zero-mark timing"), ("timebase_u_rel", "counter timebase"),
                 ("repeatability_u_rel", "repeatability (Type A)"),
                 ("timebase_correction_u_rel", "time-base correction applied")), U.ONE)
    _averaged(data, rid, path, r.intra.averaged)
    _systematic(data, rid, path, r)


def _instability_interval(r: RateEntry) -> Interval | None:
    """docs/method.md D2: sigma as its chi-square interval when resolved above the timing
    floor, else as '< L' (L never below the floor): never a normal +/- U (None: the
    result states no interval)."""
    s_val, s_lo, s_hi = (num(r.rate_instability_rel), num(r.rate_instability_lower_rel),
                         num(r.rate_instability_upper_rel))
    s_floor = num(r.rate_instability_floor_rel)
    s_iv: Interval | None = None
    s_ustd = num(r.rate_instability_ustd_rel)
    if s_val is not None and s_lo is not None and s_hi is not None:
        if r.rate_instability_resolved:
            s_iv = two_sided(s_val, s_lo, s_hi, "chi-square (N - 1 dof)",
                             _stated_or(s_ustd, (s_hi - s_lo) / 4.0))
        else:
            s_top = max(s_hi, s_floor or 0.0)
            s_iv = limit_interval(s_top, "chi-square (N - 1 dof), one-sided upper limit",
                                  _stated_or(s_ustd, s_top / 4.0))
    return s_iv


def _per_turn(qs: _Quantities, r: RateEntry, ek: float | None) -> None:
    """A1-A2: the set rate, the turns, the mean rate, the rate error, the instability with
    its timing floor, and the per-turn rates."""
    q, w_set = qs.q, qs.w_set
    q("set_rate_dps", "commanded (set) rate", f"{V.NOMINAL} {SET_RATE}", U.DEG_PER_S, w_set)
    q("turns", "whole turns timed", TURNS, U.ONE, num(r.turns))
    cr = [v for v in (num(x) for x in r.counter_rate_dps) if v is not None]
    mean = num(r.mean_rate_dps)
    if mean is None and cr:
        mean = sum(cr) / len(cr)
    eu = num(r.rate_error_u_rel)
    if mean is not None:
        q("mean_rate_dps", "mean rate over the turns (counter, docs/method.md A2)", V.MEASURED,
          U.DEG_PER_S, mean, u=eu * abs(w_set) if eu is not None and w_set else None,
          note="U = U(rate error) x |set rate|.", k=ek)
    q("rate_error_rel", "per-turn rate error (mean - set) / set (docs/method.md A2 eq. 1, "
      "signed)", f"{V.ERROR} {RATE_ERROR}", U.ONE, num(r.rate_error_rel), eu, u_stated=True,
      check="rate_error", k=ek)
    s_iv = _instability_interval(r)
    q("rate_instability_rel", "per-turn rate instability, relative std of the per-turn rates "
      "(docs/method.md A2 eq. 2)", RATE_INSTABILITY, U.ONE, num(r.rate_instability_rel),
      None if s_iv is not None else num(r.rate_instability_u_rel), u_stated=s_iv is None,
      check="rate_instability",
      interval=s_iv, note=None if s_iv is None or r.rate_instability_resolved else
      "not resolved above the timing floor: stated as < L, L the interval's upper end "
      "(docs/method.md D2)")
    q("rate_instability_floor_rel", "timing floor of the instability (counter and zero-mark "
      "timing alone, docs/method.md A1)", TIMING_FLOOR, U.ONE,
      num(r.rate_instability_floor_rel))
    if cr:
        us = _per_turn_u(r.rate_error_budget, cr)
        list_quantity(qs.data, ident(qs.rid, "counter_rate_dps"), "per-turn rates from the counter, "
                      "in turn order (docs/method.md A1)", f"{V.MEASURED} {PER_TURN}", cr,
                      U.DEG_PER_S, us, note=None if us is not None else
                      "U not stated: result.json carries no timing budget for this rate.")


def _intra_turn(qs: _Quantities, r: RateEntry) -> None:
    """A5: the intra-turn instability, raw and with the FOG's noise floor removed, with
    the floor and the corrected value's upper limit."""
    q, path = qs.q, qs.path
    intra = r.intra
    # as the PDF (docs/method.md D2): +/- U only when raw - U > the FOG floor (the
    # analysis's raw_resolved); else '< L' as [0, L], L = raw + U never below the floor
    raw_iv = (limit_interval(raw_upper, "normal, one-sided upper limit value + U",
                             _stated_or(_budget_ustd(r, "intra_turn_instability_rel")
                                        or num(intra.raw_ustd_rel),
                                        raw_upper / 4.0),
                             (1.0 + float(COVERAGE_PROBABILITY)) / 2.0)
              if intra.raw_resolved is False and (raw_upper := num(intra.raw_upper_rel))
              is not None else None)
    q("intra_turn_instability_rel", "intra-turn instability std(random part) / |set| at the "
      "FOG bandwidth (docs/method.md A5)", INTRA_TURN, U.ONE,
      num(r.intra_turn_instability_rel),
      num(r.intra_turn_instability_u_rel) if raw_iv is None else None, u_stated=True,
      check="intra_turn_instability", interval=raw_iv,
      note=None if raw_iv is None else "not resolved above the FOG noise floor: stated as "
      "< L, L = value + U (docs/method.md D2)")
    if (floor_rel := num(intra.floor_rel)) is not None:
        q("floor_rel", "FOG noise floor, relative to |set| (docs/method.md A5)", FOG_FLOOR, U.ONE,
          floor_rel, label=f"{path}.intra_turn.floor_rel")
    upper, lower = num(intra.corrected_upper_rel), num(intra.corrected_lower_rel)
    resolved = intra.resolved
    corrected = num(r.intra_turn_instability_corrected_rel)
    # as the PDF (docs/method.md A5, D2): resolved, its JCGM 101 interval; else [0, L]
    c_iv = _mc_interval(corrected, lower, upper, resolved,
                        num(intra.corrected_ustd_rel))
    q("intra_turn_instability_corrected_rel", "intra-turn instability with the FOG noise "
      "floor removed in quadrature (docs/method.md A5)", INTRA_TURN_CORRECTED, U.ONE, corrected,
      None if upper is not None else num(r.intra_turn_instability_corrected_u_rel),
      u_stated=upper is None, interval=c_iv,
      note=("not resolved above the FOG noise floor: stated as < L, L the interval's upper "
            "end" if resolved is False else None), check="intra_turn_instability_corrected")
    if upper is not None:
        q("corrected_upper_rel", "upper limit L (JCGM 101, 97.5 % quantile) of the "
          "floor-corrected intra-turn instability", INTRA_TURN_UPPER, U.ONE, upper,
          label=f"{path}.intra_turn.corrected_upper_rel")


def _averaged(data: etree._Element, rid: str, path: str, rows: Sequence[AveragedFigures]
              ) -> None:
    for j, a in enumerate(rows):
        if (angle := num(a.angle_deg)) is None:
            continue
        lst = el(data, "list", id=ident(rid, "avg", f"{angle:g}"), ref_type=AVERAGED)
        name(lst, f"random part averaged over {angle:g} deg of table angle "
                  "(docs/method.md A5)")
        p = f"{path}.intra_turn.averaged[{j}]"
        quantity(lst, None, "window", WINDOW, angle, U.DEG, label=f"{p}.angle_deg")
        v = num(a.instability_rel)
        fl = num(a.floor_rel)
        if v is not None:
            uu = num(a.u_rel)
            # as the PDF (docs/method.md D2): +/- U only when v - U > the FOG's floor over
            # the window; else '< L' as [0, L], L = v + U never below the floor
            m_res, m_upper = a.measured_resolved, num(a.measured_upper_rel)
            if m_res is None:      # an older result: the rule, here
                m_res = uu is not None and is_resolved(v, uu, floor=fl)
                m_upper = None if uu is None else max(abs(v) + uu, fl or 0.0)
            iv = (None if m_res or m_upper is None else
                  limit_interval(m_upper, "normal, one-sided upper limit value + U",
                                 _stated_or(num(a.ustd_rel), m_upper / 4.0),
                                 (1.0 + float(COVERAGE_PROBABILITY)) / 2.0))
            quantity(lst, ident(rid, "avg", f"{angle:g}", "instability_rel"),
                     "instability, relative to |set|", INTRA_TURN, v, U.ONE,
                     uu if iv is None else None, label=f"{p}.instability_rel",
                     interval=iv,
                     note="U not stated in result.json." if uu is None else
                     None if iv is None else "not resolved above the FOG's floor over the "
                     "window: stated as < L, L = value + U (docs/method.md D2)")
        if fl is not None:
            quantity(lst, None, "FOG noise floor", FOG_FLOOR, fl, U.ONE, label=f"{p}.floor_rel")
        corrected, upper = num(a.corrected_rel), num(a.corrected_upper_rel)
        if corrected is not None:
            # as the PDF (docs/method.md D2): resolved, its interval; else [0, L]
            iv = _mc_interval(corrected, num(a.corrected_lower_rel), upper, a.resolved,
                              num(a.corrected_ustd_rel))
            quantity(lst, ident(rid, "avg", f"{angle:g}", "corrected_rel"),
                     "floor-corrected", INTRA_TURN_CORRECTED, corrected, U.ONE,
                     label=f"{p}.corrected_rel", interval=iv,
                     note=None if a.resolved else "not resolved above the FOG noise "
                     "floor: stated as < L, L the interval's upper end")
        if upper is not None:
            quantity(lst, None, "upper limit L (JCGM 101, 97.5 % quantile) of the "
                     "floor-corrected value", INTRA_TURN_UPPER, upper, U.ONE,
                     label=f"{p}.corrected_upper_rel")


def _mc_interval(value: float | None, lower: float | None, upper: float | None,
                 resolved: object, ustd: float | None) -> Interval | None:
    """A floor-corrected figure's JCGM 101 interval (docs/method.md A5, D2): [lower, upper]
    when resolved, [0, L] at its one-sided level when not; its standard uncertainty the
    draws' standard deviation (JCGM 101 7.6)."""
    if value is None or upper is None:
        return None
    dist = "JCGM 101 Monte Carlo of raw^2 - floor^2"
    if resolved and lower is not None:
        return two_sided(value, lower, upper, dist, _stated_or(ustd, (upper - lower) / 4.0))
    return limit_interval(upper, dist + ", one-sided upper limit", _stated_or(ustd, upper / 4.0))


def _undetected(detected: bool | None, a: float, big_u: float | None, upper: float | None,
                factor: float | None, ustd: float | None) -> Interval | None:
    """An undetected tone's amplitude as the PDF prints it, '< L' (docs/method.md A4, D2):
    [0, L], L = a + c u(a), at 1 - alpha_1 = 1 - exp(-c^2 / 2), the level of the joint test
    whose radius is c; its standard uncertainty its budget's u_c (else U / 2). An older
    result without L: a + U at the level of k = 2."""
    if detected is not False or big_u is None:
        return None
    if upper is None or factor is None:
        return limit_interval(abs(a) + big_u, "normal, one-sided upper limit a + U",
                              big_u / 2.0, (1.0 + float(COVERAGE_PROBABILITY)) / 2.0)
    return limit_interval(upper, "joint chi-square (2 dof) interval of the tone's two "
                          "coefficients, upper limit a + c u(a)", _stated_or(ustd, big_u / 2.0),
                          1.0 - math.exp(-factor * factor / 2.0))


def _systematic(data: etree._Element, rid: str, path: str, r: RateEntry) -> None:
    for j, h in enumerate(r.harmonics):
        if num(h.order) is None:
            continue
        order = int(num(h.order) or 0)
        hid = ident(rid, "h", order)
        lst = el(data, "list", id=hid, ref_type=HARMONIC)
        name(lst, f"systematic intra-turn component, harmonic {order}: "
                  "w_set * a cos(h phi + p) (docs/method.md A4)")
        if h.detected is False:
            text_el(lst, "description", "not significant: the amplitude is consistent with "
                    "zero and its phase is meaningless")
        p = f"{path}.systematic.harmonics[{j}]"
        quantity(lst, None, "order h", HARMONIC_ORDER, order, U.ONE, label=f"{p}.order")
        for key, value, u, title, ref, unit in (
                ("amplitude_rel", h.amplitude_rel, h.amplitude_u_rel,
                 "amplitude a, relative to |set|", AMPLITUDE, U.ONE),
                ("phase_deg", h.phase_deg, h.phase_u_deg, "phase p", PHASE, U.DEG)):
            v = num(value)
            if v is not None:
                uu = num(u)
                quantity(lst, ident(hid, key), title, ref, v, unit, uu, label=f"{p}.{key}",
                         note=None if uu is not None else "U not stated in result.json.",
                         interval=_undetected(h.detected, v, uu, num(h.amplitude_upper_rel),
                                              num(h.interval_factor),
                                              _budget_ustd(r, f"systematic.harmonics[{j}]."
                                                              "amplitude_rel"))
                         if key == "amplitude_rel" else None)
    m = r.mains
    if m is not None and num(m.amplitude_dps) is not None:
        mid = ident(rid, "mains")
        lst = el(data, "list", id=mid, ref_type=MAINS)
        name(lst, "mains-frequency ripple, one tone fitted in time (docs/method.md A4)")
        if m.detected is False:
            text_el(lst, "description", "not significant")
        p = f"{path}.systematic.mains"
        # the frequency has no U to state; the amplitude and phase have theirs
        for key, value, u, states_u, title, ref, unit in (
                ("frequency_hz", m.frequency_hz, None, False, "frequency", FREQUENCY, U.HERTZ),
                ("amplitude_dps", m.amplitude_dps, m.amplitude_u_dps, True, "amplitude",
                 AMPLITUDE, U.DEG_PER_S),
                ("phase_deg", m.phase_deg, m.phase_u_deg, True, "phase", PHASE, U.DEG)):
            v = num(value)
            if v is not None:
                uu = num(u) if states_u else None
                quantity(lst, ident(mid, key), title, ref, v, unit, uu, label=f"{p}.{key}",
                         note=None if uu is not None or not states_u
                         else "U not stated in result.json.",
                         interval=_undetected(m.detected, v, uu, num(m.amplitude_upper_dps),
                                              num(m.interval_factor),
                                              _budget_ustd(r, "systematic.mains.amplitude_dps"))
                         if key == "amplitude_dps" else None)


def _or_not_recorded(value: float | None) -> str:
    return NOT_RECORDED if value is None else str(value)


def _pair_result(res: etree._Element, axis: str, i: int, p: PairEntry) -> None:
    rate = num(p.rate_dps)
    pid = ident("pair", axis, f"{rate:g}" if rate is not None else i)
    path = f"axes.{axis}.pairs[{i}]"
    result = el(res, "result", id=pid, ref_type=PAIR)
    name(result, f"Axis {axis}, cross-calibration of the FOG at +/-{rate:g} deg/s (docs/method.md "
                 "A3 eqs. 5-6)" if rate is not None else f"Axis {axis}, pair {i + 1}")
    if p.method:
        text_el(result, "description", f"method {p.method}"
                + (f"; bias drift {p.drift_source}" if p.drift_source else ""))
    data = el(result, "data")
    for key, value, u, title, ref, unit in (
            ("rate_dps", p.rate_dps, None, "pair rate magnitude", V.NOMINAL, U.DEG_PER_S),
            ("k", p.k, p.k_u, "FOG scale k (eq. 5)", f"{V.MEASURED} {FOG_SCALE}", U.ONE),
            ("w0_dps", p.w0_dps, p.w0_u_dps, "FOG bias w0 (eq. 6)",
             f"{V.MEASURED} {FOG_BIAS}", U.DEG_PER_S),
            ("drift_dps_per_h", p.drift_dps_per_h, p.drift_u_dps_per_h, "FOG bias drift "
             "during the pair, deg/s per hour", f"{V.MEASURED} {FOG_BIAS_DRIFT}",
             r"\degree\second\tothe{-1}\hour\tothe{-1}")):
        v = num(value)
        if v is None:
            continue
        uu = num(u)
        quantity(data, ident(pid, key), title, ref, v, unit, uu, label=f"{path}.{key}",
                 note=None if uu is not None or key == "rate_dps" else
                 "U not stated in result.json.")
