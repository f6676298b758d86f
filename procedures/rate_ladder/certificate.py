"""The rate ladder's part of its calibration certificate (docs/method.md part A).

The certificate (bench/app/certificate/build.py) asks the kind for these through
`CertificateParts`: the method statement, the source paper's deviations, the results per
axis (A1-A5) with their plots, and the annex of per-turn counter rates. Values are printed
with the certificate's own rounding rules and helpers, so they read as the rest of it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from msgspec import UnsetType

from bench.analysis.coverage import COVERAGE_FORMULA, COVERAGE_RULE, DOF_INFINITE
from bench.analysis.random_part import std_u_rel
from bench.analysis.turns import RATE_ERROR_U_FORMULA, REPEATABILITY_FORMULA
from bench.report.certificate import methods
from bench.report.certificate.model import Block, Para, Section, Table
from bench.report.certificate.parts import (
    CertificateParts,
    Sources,
    TitledBlocks,
    figure_of,
    num,
    rate_text,
    text_of,
    verdict_label,
    vu_text,
)
from bench.report.certificate.rounding import (
    PERCENT,
    PPM,
    RESOLUTION_RULE,
    Presented,
    RelUnit,
    format_sig,
    format_value_u,
    is_resolved,
    present,
    present_phase,
    present_std,
    rel_unit,
)
from bench.report.result_frame import Check
from procedures.rate_ladder import plots
from procedures.rate_ladder.codec import conform_body, ladder_model
from procedures.rate_ladder.result import (
    UNSIGNED,
    LadderAxis,
    LadderResult,
    NoiseFloor,
    PairEntry,
    RateEntry,
    RateErrorBudget,
)

# -- the method statement (docs/method.md part A, restated) ---------------------------------

A_TEXT: tuple[Para, ...] = (
    Para(methods.A_REFERENCE),
    Para("Measuring chain. An optical slot sensor on the base gives one pulse per revolution "
         "(the zero mark); a frequency counter times the period T between zero marks; a FOG on "
         "the table top streams the instantaneous rate. The counter sees only |T|: the sign of "
         "the per-turn rate is the sign of the commanded rate."),
    Para("A1 Per-turn rate (fixed-angle method), one value per revolution i:", "strong"),
    Para("ω_i = 360° / T_i", "formula"),
    Para("Timing of one zero-mark edge (standard uncertainty), of one period (two independent "
         "edges) and the per-turn rate error it causes:", "body"),
    Para("Δ_edge = √(Δ_counter² + Δ_trigger²);   ΔT = √2 · Δ_edge;   Δω/ω ≈ ΔT / T",
         "formula"),
    Para("The source paper's ΔT = √(Δ_counter² + Δ_trigger²) is written per edge here; a "
         "period has two edges. The timing floor of σ printed with the results is ΔT / T, "
         "T the mean period: the σ that edge timing alone would give.", "note"),
    Para("A2 Per-turn rate error and instability over N turns at the commanded rate ω_set:",
         "strong"),
    Para("δ = (mean(ω_i) − ω_set) / ω_set     (eq. 1, signed; computed exactly so)",
         "formula"),
    Para("Sign convention: ω_set and ω_i carry the sign of the direction, so δ > 0 means the "
         "table turns faster than commanded in either direction and δ < 0 slower. The source "
         "paper's eq. 1 is |mean − ω_set| / |ω_set|, which is |δ|; the conformity checks "
         "compare |δ| with the tolerance. mean(ω_i) is the mean over whole turns, N·360° / "
         "(t_N − t_0).", "note"),
    Para("σ = √( Σ (ω_i − mean(ω))² / (N − 1) ) / |mean(ω)|     (eq. 2)", "formula"),
    Para("U of δ combines the timing of each window's two end edges, the counter's "
         "timebase (rectangular) and the turn-to-turn repeatability, a Type A term with its "
         "degrees of freedom; k is the t-factor of the effective degrees of freedom "
         "(docs/method.md A2, D1):", "body"),
    Para(REPEATABILITY_FORMULA, "formula"),
    Para(RATE_ERROR_U_FORMULA, "formula"),
    Para("Note on eq. 2: the source paper prints eq. 2 without the square root (a variance "
         "divided by the mean, which has units of °/s). This certificate uses the relative "
         "standard deviation above, which is what the paper's numbers and its text describe.",
         "note"),
    Para("A3 Cross-calibration of the FOG against the counter for each ± pair of rates "
         "(ω+ = −ω−); FOG model ω_fog = k·ω_true + ω0, with FOG means taken over exactly "
         "the turns the counter timed:", "strong"),
    Para("k = (Ω_fog+ − Ω_fog−) / (Ω_cnt+ − Ω_cnt−)   (eq. 5);   "
         "ω0 = Ω_fog+ − k·Ω_cnt+   (eq. 6);   ω_true(t) = (ω_fog(t) − ω0) / k", "formula"),
    Para("A4 Systematic intra-turn component: every FOG sample is given its table angle φ "
         "from the zero-mark timestamps and the integrated calibrated rate (angle domain), "
         "and the harmonic model Δω_sys(φ) = ω_set·Σ a_h cos(hφ + p_h), h = 1…H, plus a "
         "mains-frequency tone in time, is fitted by linear least squares; amplitude and phase "
         "are reported with their uncertainties. The paper's binned average by angle is kept "
         "for comparison in the plots.", "body"),
    Para("A5 Random component and intra-turn instability:", "strong"),
    Para("Δω_rand = ω_true − Δω_sys(φ) − ω_set;   intra-turn instability = std(Δω_rand) / "
         "|ω_set|", "formula"),
    Para("It is reported at the FOG's output bandwidth (raw), with the FOG's own noise floor "
         "removed in quadrature (floor-corrected), and for the random part averaged over "
         "1°, 10° and 360° of table angle, so it can be read against a rate-table "
         "datasheet.", "body"),
    Para("D1 The coverage factor of every U (docs/method.md D1):", "strong"),
    Para(COVERAGE_FORMULA, "formula"),
    Para(COVERAGE_RULE, "note"),
)

A_IMPROVEMENTS: tuple[str, ...] = (
    "Angle assignment from zero-mark timestamps and the integrated calibrated rate, instead of "
    "the paper's sample index × ω_set / f mapping (which accumulates error when the table's "
    "rate is off).",
    "Least-squares fit of harmonics 1…H in angle and of the mains tone in time, with "
    "uncertainties, in place of the binned average alone.",
    "The FOG's noise floor (from a record at rest or from the pair's own data) is removed in "
    "quadrature; the raw figure is printed beside the corrected one.",
    "Intra-turn instability is also given averaged over 1°, 10° and 360°.",
)

SEQUENCE_TEXT = {
    "+-+": "Halves of each pair run in the symmetric order +ω, −ω, +ω (the + turns split "
           "around the − half), so a linear FOG bias drift cancels in k and ω0; the paper ran "
           "+ω then −ω.",
    "+-": "Halves of each pair run in the paper's order +ω then −ω; a FOG bias drift during the "
          "pair enters k and ω0 and is part of their uncertainty.",
}

# -- what the certificate asks ---------------------------------------------------------------

class LadderCertificate(CertificateParts):
    """The rate ladder's answers to the certificate (its DCC: procedures/rate_ladder/
    dcc.py, the kind's `dcc` part)."""

    certificate_procedure_name = "rate ladder (docs/method.md part A)"
    certificate_procedure_id = ("RB-RL", "A", methods.PAPER_A)
    certificate_stand_label = "Rate table"
    certificate_measured = (
        ("rate_error", "per-turn rate error"),
        ("rate_instability", "per-turn rate instability"),
        ("systematic", "once-per-revolution and higher harmonics of the rate"),
        ("mains", "mains-frequency ripple"),
        ("intra_turn_instability", "intra-turn instability"),
        # over 360° the rate stability is σ of the per-turn rates (rate_instability)
        ("stability_over_angle", "rate stability over 1° and 10° (FOG)"))
    certificate_quantities = {
        "rate_error": "per-turn rate error |δ|",
        "rate_instability": "per-turn rate instability σ",
        "intra_turn_instability": "intra-turn instability",
        "intra_turn_instability_corrected": "intra-turn instability, floor-corrected",
    }
    certificate_unsigned = UNSIGNED
    #: the ladder's part of result.json checked by its codec (`Sources`' conform_result)
    result_conform = staticmethod(conform_body)

    def certificate_recognises(self, src: Sources) -> bool:
        return "axes" in src.result     # CONTRACT §3's binding keys: results per axis

    def certificate_identification(self, src: Sources) -> Sequence[tuple[str, str]]:
        return [("Item: what was calibrated",
                 ", ".join(f"axis {a}" for a in _ladder(src).axes)
                 + "; rates are signed in each axis's positive sense (the drive's "
                   "positive count direction), angles from the zero mark")]

    def certificate_method(self, src: Sources) -> Sequence[Block]:
        return A_TEXT

    def certificate_method_deviations(self, src: Sources) -> Sequence[Block]:
        seq = src.frame.method.get("sequence")
        items = list(A_IMPROVEMENTS)
        if seq in SEQUENCE_TEXT:
            items.insert(0, SEQUENCE_TEXT[seq])
        return [Para("Where this procedure differs from the source paper's method "
                     "(docs/method.md A3-A5):", "strong"), *(Para(f"• {t}") for t in items)]

    def certificate_checks(self, src: Sources) -> list[Check]:
        """The per-rate judgements of the analysis (a result without checks[])."""
        out: list[Check] = []
        for axis, r in _ladder(src).rates():
            j = r.judgement
            if isinstance(j, UnsetType) or r.verdict is None:
                continue
            rule = str(j.get("decision_rule", "simple"))
            out.append(Check.of({
                "axis": axis, "set_rate_dps": r.set_rate_dps, "quantity": "rate_error",
                "value_rel": r.rate_error_rel, "u_rel": r.rate_error_u_rel,
                "tolerance_rel": j.get("tolerance_rel"), "verdict": r.verdict,
                "rule": "simple" if rule.startswith("simple") else rule,
                "capability_ratio": j.get("capability_ratio"),
                "capability_ok": j.get("capable")}))
        return out

    def certificate_sections(self, src: Sources, number: str,
                             checks: Sequence[Check]) -> list[Section]:
        return _ladder_results(src, number, checks)

    def certificate_annexes(self, src: Sources) -> Sequence[TitledBlocks]:
        if not any(r.counter_rate_dps for _, r in _ladder(src).rates()):
            return ()
        return (("Per-turn counter rates", _per_turn_annex(src)),)


def _ladder(src: Sources) -> LadderResult:
    """The ladder's result model of the conformed result, decoded once (codec.py)."""
    return src.model(ladder_model)


# -- the results -----------------------------------------------------------------------------

def _tolerances(checks: Iterable[Check], axis: str
                ) -> dict[str, list[tuple[float, float]]]:
    out: dict[str, list[tuple[float, float]]] = {}
    for c in checks:
        rate, tol = num(c.set_rate_dps), num(c.tolerance_rel)
        if c.axis == axis and rate is not None and tol is not None:
            out.setdefault(str(c.quantity), []).append((abs(rate), tol))
    return {k: sorted(set(v)) for k, v in out.items()}



def _instability_u(r: RateEntry) -> tuple[float | None, bool]:
    """U of eq. 2's sigma: the result's, else the chi-square approximation (k = 2)."""
    u = num(r.rate_instability_u_rel)
    if u is not None:
        return u, False
    s, n = num(r.rate_instability_rel), len(r.counter_rate_dps)
    u = std_u_rel(s, n or int(r.turns or 0))
    return u, u is not None


def sigma_presented(r: RateEntry, u: float | None, scale: float = 1.0) -> Presented:
    """Eq. 2's σ under the one rule (docs/method.md D2), with the timing floor as its zero:
    resolved when its chi-square lower limit > floor (the analysis's
    `rate_instability_resolved`), printed as its interval 'σ [lower, upper]'; else '< L',
    L the one-sided chi-square upper limit (`rate_instability_upper_rel`), never below the
    floor (`present_std`, which the station prints with too)."""
    return present_std(num(r.rate_instability_rel), u, scale,
                       lower=num(r.rate_instability_lower_rel),
                       upper=num(r.rate_instability_upper_rel),
                       floor=num(r.rate_instability_floor_rel),
                       resolved=r.rate_instability_resolved)


def _u_of_std(s: float | None, n: float | None) -> float | None:
    """U (k = 2) of a standard deviation from n values, when the result does not give it."""
    n = num(n)
    return None if n is None else std_u_rel(s, int(n))


@dataclass(frozen=True)
class Averaged:
    """The random part averaged over windows of `angle_deg` of table angle (docs/method.md A5)."""

    angle_deg: float
    raw: float | None
    u: float | None
    u_approx: bool
    floor: float | None
    corrected: float | None
    blocks: int | None
    upper: float | None = None        # upper end of the corrected figure's interval
    resolved: bool | None = None
    lower: float | None = None        # its lower end (JCGM 101, docs/method.md A5)
    measured_resolved: bool | None = None   # the analysis's D2 decision (None: older)
    measured_upper: float | None = None     # its L = value + U, never below the floor

    @property
    def sensitivity(self) -> float | None:
        """The smallest table figure these n windows could resolve: where the excess
        variance equals 2 u of the measured variance, (8 / (n - 1))^(1/4) * measured."""
        if self.raw is None or not self.blocks or self.blocks < 2:
            return None
        floor: float = self.raw * (8.0 / (self.blocks - 1)) ** 0.25
        return floor


def _averaged(r: RateEntry) -> list[Averaged]:
    """Averages over 1/10/360 deg, from `intra_turn.averaged`."""
    out = []
    for d in r.averaged:
        if (angle_deg := num(d.angle_deg)) is None:
            continue
        raw, u = num(d.instability_rel), num(d.u_rel)
        approx = u is None
        if approx:
            u = _u_of_std(raw, d.blocks)
        corrected, upper = num(d.corrected_rel), num(d.corrected_upper_rel)
        resolved = d.resolved
        if resolved is None:   # an older result: the k = 2 test on the excess variance
            resolved = corrected is not None and corrected != 0 and u is not None \
                and raw is not None and corrected ** 2 > 2 * raw * u
        if upper is None and raw is not None and u is not None:
            fl = num(d.floor_rel) or 0.0
            upper = math.sqrt(max(raw * raw - fl * fl, 0.0) + 2 * raw * u)
        out.append(Averaged(angle_deg, raw, u, approx and u is not None, num(d.floor_rel),
                            corrected, d.blocks, upper, bool(resolved),
                            num(d.corrected_lower_rel), d.measured_resolved,
                            num(d.measured_upper_rel)))
    return sorted(out, key=lambda x: x.angle_deg)


def _ladder_results(src: Sources, number: str, checks: Sequence[Check]
                    ) -> list[Section]:
    axes = _ladder(src).axes
    out = [Section(number, "Results", (Para(
        "Per axis, commanded rate and direction. Each value is followed by its expanded "
        "uncertainty U for about 95 % (k = 2, or k = t_95.45(ν_eff) where its budget in "
        "the annex states finite ν_eff; docs/method.md D1), or by its coverage interval. "
        "Signed rates: + is the table's positive sense."),
        Para("Quantities that may not be resolved (docs/method.md D2). " + RESOLUTION_RULE,
             "note")),
        )]
    sub = 0
    # one unit per quantity on the whole certificate, whatever the axis
    every = [r for ax in axes.values() for r in ax.rates]
    for axis, ax in axes.items():
        sub += 1
        out.append(Section(f"{number}.{sub}", f"Axis {axis}",
                           _axis_blocks(axis, ax, checks, every), level=2))
    figs = _across_axes(axes)
    if figs:
        sub += 1
        out.append(Section(f"{number}.{sub}", "All axes: trends with rate", tuple(figs), level=2))
    if not axes:
        out.append(Section(f"{number}.1", "No results", (Para(
            "The result carries no axis results: nothing was measured to completion."),),
            level=2))
    return out


def _axis_blocks(axis: str, ax: LadderAxis, checks: Sequence[Check],
                 every: list[RateEntry]) -> tuple[Block, ...]:
    """One axis's results, in the method's order (A1-A2 per turn, A3 the FOG's
    cross-calibration, A4 the systematic component, A5 within the turn); `every` is every
    axis's rates, so that one quantity has one unit on the whole certificate."""
    blocks = _per_turn_blocks(axis, ax.rates, checks, every)
    if ax.pairs:
        blocks.append(_pairs_table(axis, ax.pairs))
    blocks += _systematic_blocks(axis, ax.rates, every)
    blocks += _intra_blocks(axis, ax.rates, ax.noise_floor, every)
    return tuple(blocks)


def _per_turn_blocks(axis: str, rates: Sequence[RateEntry], checks: Sequence[Check],
                     every: list[RateEntry]) -> list[Block]:
    """A1-A2: each rate's mean, rate error and per-turn instability with its timing floor,
    the rate error's budget, and their plot against the rate."""
    blocks: list[Block] = []
    err_unit = rel_unit(*[v for r in every for v in (num(r.rate_error_rel),
                                                      num(r.rate_error_u_rel))],
                        *[t for c in checks if c.quantity == "rate_error"
                          for t in (num(c.tolerance_rel),)])
    inst_us = [_instability_u(r) for r in rates]
    inst_unit = rel_unit(*[num(r.rate_instability_rel) for r in every],
                         *[_instability_u(r)[0] for r in every])
    rows = []
    approximated = False
    unresolved_sigma = False
    for r, (iu, approx) in zip(rates, inst_us, strict=True):
        approximated |= approx
        set_rate = num(r.set_rate_dps)
        mean = num(r.mean_rate_dps)
        cr = [v for v in (num(x) for x in r.counter_rate_dps) if v is not None]
        if mean is None and cr:
            mean = sum(cr) / len(cr)
        eu = num(r.rate_error_u_rel)
        mean_u = eu * abs(set_rate) if eu is not None and set_rate else None
        sigma = sigma_presented(r, iu, inst_unit.scale)
        unresolved_sigma |= not sigma.resolved
        rows.append((rate_text(set_rate), text_of(r.turns),
                     format_value_u(mean, mean_u, signed=True, sig_without_u=10).joined(),
                     vu_text(r.rate_error_rel, eu, err_unit, signed=True),
                     sigma.text + ("*" if approx and sigma.resolved else ""),
                     format_sig(floor_rel * inst_unit.scale, 2)
                     if (floor_rel := num(r.rate_instability_floor_rel)) is not None
                     else "—",
                     verdict_label(r.verdict)))
    notes = ["Timing floor of σ = ΔT / T, with ΔT = √2 · Δ_edge the timing of one period "
             "(section 3, A1): the σ the counter's and the zero-mark sensor's timing errors "
             "alone would give."]
    notes.append("σ [lower, upper]: its 95 % chi-square interval (N − 1 degrees of freedom, "
                 "normal per-turn rates), printed so because it is not symmetric.")
    if unresolved_sigma:
        notes.append("'< L': σ is not resolved above the timing floor (its 2.5 % chi-square "
                     "lower limit ≤ floor): L is its one-sided 97.5 % upper limit for normal "
                     "per-turn rates (chi-square, N − 1 degrees of freedom), never below the "
                     "floor. In a conformity check such a σ conforms when L is within the "
                     "tolerance, and is not assessed only when it is not (docs/method.md D2, "
                     "the one rule for '< L').")
    if approximated:
        notes.append("* U of σ from the chi-square approximation U = 2σ/√(2(N−1)) for N turns "
                     "(normal per-turn rates); the result did not carry it.")
    blocks.append(Table(
        ("Set rate, °/s", "Turns", "Mean rate ± U, °/s",
         f"Rate error δ ± U, {err_unit.name}", f"Instability σ [interval], {inst_unit.name}",
         f"Timing floor of σ, {inst_unit.name}", "Verdict"),
        tuple(rows), widths=(0.9, 0.6, 2.8, 1.8, 1.8, 1.1, 0.9), align="rcrrrrc",
        caption=f"Axis {axis}: per-turn rate error and instability (docs/method.md A1-A2, eqs. 1-2)",
        notes=tuple(notes)))
    budget = _rate_error_budget(axis, rates)
    if budget is not None:
        blocks.append(budget)
    blocks += figure_of(f"Axis {axis}: per-turn rate error and instability vs rate, both "
                      "directions (cf. paper figs. 4-5)",
                      plots.per_turn, axis, rates, _tolerances(checks, axis),
                      (f"δ, {err_unit.name}", err_unit.scale),
                         (f"σ, {inst_unit.name}", inst_unit.scale))
    return blocks


def _pairs_table(axis: str, pairs: Sequence[PairEntry]) -> Table:
    """A3: the FOG's scale factor k and bias ω0 per ± pair (with its bias drift when the
    analysis estimated one), and which half of a resumed pair came from which session."""
    prow = []
    has_drift = any(num(p.drift_dps_per_h) is not None for p in pairs)
    for p in pairs:
        w0, w0u = num(p.w0_dps), num(p.w0_u_dps)
        row = [f"±{num(p.rate_dps) or 0:g}", format_value_u(p.k, p.k_u).joined(),
               vu_text(w0, w0u, signed=True),
               format_value_u(w0, w0u, 3600.0, signed=True).joined()]
        if has_drift:
            row.append(vu_text(p.drift_dps_per_h, p.drift_u_dps_per_h, signed=True))
        prow.append(tuple(row))
    header = ["Pair, °/s", "k ± U", "ω0 ± U, °/s", "ω0 ± U, °/h"]
    notes = []
    if has_drift:
        header.append("Bias drift ± U, °/s per h")
        methods_used = sorted({CALIBRATION_METHODS.get(p.method, p.method)
                               for p in pairs if p.method})
        sources = sorted({p.drift_source for p in pairs if p.drift_source})
        notes.append("ω0 is the bias at the pair's reference time; the FOG's bias drift "
                     "during the pair is estimated and removed"
                     + (f" ({'; '.join(methods_used)}" if methods_used else "")
                     + (f"; drift from {', '.join(sources)})" if sources else
                        (")" if methods_used else "")) + ".")
    for p in pairs:  # a resumed pair: which half came from which session (docs/resume.md)
        hs = p.half_sessions
        if len(set(hs)) > 1:
            notes.append(f"Pair ±{num(p.rate_dps) or 0:g} °/s was resumed: "
                         + ", ".join(f"half {i + 1} from session {s}"
                                     for i, s in enumerate(hs))
                         + f". FOG bias {p.bias_model}.")
    return Table(tuple(header), tuple(prow),
                 widths=(1.0, 2.4, 2.1, 1.9, 2.1)[:len(header)], align="rrrrr"[:len(header)],
                 caption=f"Axis {axis}: FOG cross-calibration per ± pair "
                         "(docs/method.md A3, eqs. 5-6)", notes=tuple(notes))


def _harmonic_rows(rates: Sequence[RateEntry], amp_unit: RelUnit, factors: set[float]
                   ) -> list[tuple[str, ...]]:
    """A4: each fitted harmonic per rate, relative and in °/s, with its phase; an
    undetected tone as '< L' (D2). The tones' interval factors c are added to `factors`."""
    sys_rows: list[tuple[str, ...]] = []
    for r in rates:
        for h in r.harmonics:
            a, au = num(h.amplitude_rel), num(h.amplitude_u_rel)
            w = abs(num(r.set_rate_dps) or 0.0)
            detected = h.detected
            resolved = bool(detected) if detected is not None else is_resolved(a, au)
            # docs/method.md A4, D2: an undetected tone is '< L', L = a + c·u(a) (analysis)
            upper = num(h.amplitude_upper_rel)
            if (c := num(h.interval_factor)) is not None:
                factors.add(round(c, 2))
            sys_rows.append((rate_text(r.set_rate_dps), text_of(h.order),
                             present(a, au, amp_unit.scale, resolved=resolved,
                                     upper=upper).text,
                             present(a * w if a is not None else None,
                                     au * w if au is not None else None,
                                     resolved=resolved,
                                     upper=upper * w if upper is not None else None).text,
                             present_phase(num(h.phase_deg), num(h.phase_u_deg), resolved)))
    return sys_rows


def _mains_rows(rates: Sequence[RateEntry], factors: set[float]) -> list[tuple[str, ...]]:
    """A4: the mains-frequency ripple per rate, in °/s and relative, with its phase."""
    mains_rows: list[tuple[str, ...]] = []
    for r in rates:
        m = r.mains
        if m is not None and m.stated:
            w = abs(num(r.set_rate_dps) or 0.0)
            a, au = num(m.amplitude_dps), num(m.amplitude_u_dps)
            detected = m.detected
            resolved = bool(detected) if detected is not None else is_resolved(a, au)
            upper = num(m.amplitude_upper_dps)
            if (c := num(m.interval_factor)) is not None:
                factors.add(round(c, 2))
            mains_rows.append((rate_text(r.set_rate_dps), text_of(m.frequency_hz),
                               present(a, au, resolved=resolved, upper=upper).text,
                               present(a / w if a is not None and w else None,
                                       au / w if au is not None and w else None,
                                       PERCENT.scale, resolved=resolved,
                                       upper=upper / w if upper is not None and w
                                       else None).text,
                               present_phase(num(m.phase_deg), num(m.phase_u_deg), resolved)))
    return mains_rows


def _systematic_blocks(axis: str, rates: Sequence[RateEntry], every: list[RateEntry]
                       ) -> list[Block]:
    """A4: the fitted harmonics and the mains ripple, and the systematic component plotted
    against the table angle."""
    blocks: list[Block] = []
    factors: set[float] = set()      # c of the tones' intervals a ± c·u(a) (A4)
    amp_unit = rel_unit(*[num(h.amplitude_rel) for r in every for h in r.harmonics])
    sys_rows = _harmonic_rows(rates, amp_unit, factors)
    mains_rows = _mains_rows(rates, factors)
    c_text = (" (c = " + ", ".join(f"{c:.2f}" for c in sorted(factors)) + " here)"
              if factors else "")
    if sys_rows:
        blocks.append(Table(("Set rate, °/s", "Order h", f"Amplitude ± U, {amp_unit.name} "
                             "of ω_set", "Amplitude ± U, °/s", "Phase p_h ± U, °"),
                            tuple(sys_rows), widths=(1.1, 0.8, 2.4, 2.2, 1.8), align="rcrrr",
                            caption=f"Axis {axis}: systematic intra-turn component, fitted "
                                    "harmonics Δω_sys = ω_set·Σ a_h cos(hφ + p_h) "
                                    "(docs/method.md A4)",
                            notes=("A tone's coverage interval is a ± c·u(a), u(a) = U/2 "
                                   "its budget's standard uncertainty and c = √(−2 ln α₁) "
                                   "the radius of the joint test of its two coefficients, "
                                   "α₁ = 1 − 0.95^(1/m) for the m tones tested in the "
                                   f"direction{c_text} (docs/method.md A4). '< L': the "
                                   "interval reaches zero, the tone is not detected (the "
                                   "one rule of docs/method.md D2); L = a + c·u(a) is its "
                                   "one-sided upper limit, and its phase, which then means "
                                   "nothing, is printed '—'.",)))
    if mains_rows:
        blocks.append(Table(("Set rate, °/s", "Frequency, Hz", "Amplitude ± U, °/s",
                             "Amplitude ± U, % of ω_set", "Phase ± U, °"), tuple(mains_rows),
                            widths=(1.1, 1.0, 2.2, 2.2, 1.6), align="rrrrr",
                            caption=f"Axis {axis}: mains-frequency ripple, fitted in time "
                                    "(docs/method.md A4)",
                            notes=("One tone of fixed frequency and phase over each "
                                   "direction's record. Grid-frequency wander during the "
                                   "record (of the order of 1 / record length or more) "
                                   "spreads the tone and lowers the amplitude found; "
                                   "'< L' and '—' as for the harmonics.",)))
    blocks += figure_of(f"Axis {axis}: systematic component vs table angle with the fitted "
                      "harmonics (cf. paper figs. 8-9)",
                      plots.systematic, axis, rates, amp_unit.scale, amp_unit.name)
    return blocks


def _corrected_cell(r: RateEntry, unit: RelUnit) -> str:
    """Floor-corrected instability under the one rule (docs/method.md D2): its JCGM 101
    interval 'value [lower, upper]' when resolved, else its upper limit '< L' (never a
    bare value)."""
    intra = r.intra
    value = num(r.intra_turn_instability_corrected_rel)
    u = num(r.intra_turn_instability_corrected_u_rel)
    upper, lower = num(intra.corrected_upper_rel), num(intra.corrected_lower_rel)
    resolved = intra.resolved
    if resolved and value is not None and upper is not None and lower is not None:
        return present(value, None, unit.scale, resolved=True,
                       interval=(lower, upper)).text
    if u is not None and resolved is not False:
        return present(value, u, unit.scale, resolved=True).text
    if resolved and value is not None and upper is not None and upper > value:
        # an older result without the interval's lower end: the limit's distance
        return present(value, upper - value, unit.scale, resolved=True).text
    if upper is None and value == 0.0:
        return "0 (noiseless FOG)"   # a simulated FOG without noise: nothing to remove
    return present(value, None, unit.scale, resolved=False, upper=upper).text


#: the analysis's names for its cross-calibration methods, in words (docs/method.md A3)
CALIBRATION_METHODS = {
    "lsq-drift": "k, ω0 and a linear bias drift fitted by least squares to the halves' means",
    "eq5-6": "k and ω0 from eqs. 5-6",
    "eq5-6, drift-corrected": "k and ω0 from eqs. 5-6 after removing the bias drift",
}

BUDGET_TERMS = (("timing_u_rel", "zero-mark timing"), ("timebase_u_rel", "counter timebase"),
                ("repeatability_u_rel", "repeatability (Type A)"),
                ("timebase_correction_u_rel", "time-base correction applied"))


def _stated(b: RateErrorBudget, key: str) -> float | None:
    """A term of the rate error's budget by its result.json key (BUDGET_TERMS), None when
    the budget does not state it."""
    return num(getattr(b, key))


def _rate_error_budget(axis: str, rates: Sequence[RateEntry]) -> Table | None:
    """The standard uncertainties behind U of the rate error (docs/method.md A1-A2)."""
    budgets = [(r, b) for r in rates if (b := r.rate_error_budget) is not None]
    if not budgets:
        return None
    terms = [(k, name) for k, name in BUDGET_TERMS
             if any(_stated(b, k) is not None for _, b in budgets)]
    unit = rel_unit(*[_stated(b, k) for _, b in budgets for k, _ in terms],
                    *[num(r.rate_error_u_rel) for r, _ in budgets])
    rows = []
    for r, b in budgets:
        cells = [format_sig((_stated(b, k) or math.nan) * unit.scale, 2) for k, _ in terms]
        u = num(r.rate_error_u_rel)
        nu = num(b.dof_eff)
        rows.append((rate_text(r.set_rate_dps), *cells,
                     "∞" if nu is None or nu > DOF_INFINITE else f"{nu:.1f}",
                     f"{num(b.coverage_factor) or 2.0:.2f}",
                     format_sig(u * unit.scale, 2) if u is not None else "n/a"))
    first = budgets[0][1]
    parts = []
    for key, text, scale, unit_name in (("timestamp_u_s", "counter single-shot timestamp", 1e9, "ns"),
                                        ("trigger_jitter_s", "zero-mark edge jitter", 1e9, "ns"),
                                        ("timebase_limit_rel", "timebase limit", 1e6, "ppm"),
                                        ("time_tie_u_s", "time tie to the FOG axis (moves "
                                         "the FOG window and the harmonics' phase, not the "
                                         "counter's rate)", 1e6, "µs")):
        v = _stated(first, key)
        if v is not None:
            parts.append(f"{text} {format_sig(v * scale, 2)} {unit_name}")
    notes = ["Standard uncertainties (k = 1), relative to the set rate; U = k·√(Σu²), "
             "k = t_95.45(ν_eff) to two decimals, ν_eff by Welch-Satterthwaite with the "
             "repeatability's degrees of freedom (docs/method.md A2, D1; each rate's full "
             "budget is in the annex)."]
    if parts:
        notes.append("Inputs: " + "; ".join(parts) + " (docs/method.md A1: ΔT = √(Δ_counter² + "
                     "Δ_trigger²)).")
    header = ("Set rate, °/s", *[f"u({name}), {unit.name}" for _, name in terms],
              "ν_eff", "k", f"U, {unit.name}")
    return Table(header, tuple(rows), widths=(1.1, *([1.6] * len(terms)), 0.7, 0.6, 1.1),
                 align="r" * len(header),
                 caption=f"Axis {axis}: uncertainty budget of the per-turn rate error",
                 notes=tuple(notes))


def _intra_blocks(axis: str, rates: Sequence[RateEntry], floor: NoiseFloor | None,
                  every: list[RateEntry]) -> list[Block]:
    if not any(r.intra_turn_instability_rel is not None for r in rates):
        return []
    raws = [num(r.intra_turn_instability_rel) for r in rates]
    raw_us: list[float | None] = []
    approx = False
    for r, raw in zip(rates, raws, strict=True):
        u = num(r.intra_turn_instability_u_rel)
        if u is None:
            u = _u_of_std(raw, r.intra.samples)
            approx |= u is not None
        raw_us.append(u)
    floors = [num(r.intra.floor_rel) for r in rates]
    raw_unit = rel_unit(*[num(r.intra_turn_instability_rel) for r in every])
    corr_unit = rel_unit(*[num(r.intra_turn_instability_corrected_rel) for r in every],
                         *[num(r.intra.corrected_upper_rel) for r in every])
    rows = []
    for r, raw, u, fl in zip(rates, raws, raw_us, floors, strict=True):
        # docs/method.md D2: raw ± U only when raw − U lies above the FOG floor (the
        # analysis's `intra_turn.raw_resolved`), else '< L', L = raw + U, never below it
        raw_resolved = r.intra.raw_resolved
        raw_text = (present(raw, u, raw_unit.scale, floor=fl) if raw_resolved is None else
                    present(raw, u, raw_unit.scale, resolved=raw_resolved,
                            upper=r.intra.raw_upper_rel, floor=fl)).text
        rows.append((rate_text(r.set_rate_dps),
                     raw_text + ("*" if u is not None and approx
                                 and r.intra_turn_instability_u_rel is None
                                 and "±" in raw_text else ""),
                     format_value_u(fl, None, raw_unit.scale, sig_without_u=2).value
                     if fl is not None else "—",
                     _corrected_cell(r, corr_unit)))
    header = ("Set rate, °/s", f"Raw ± U, {raw_unit.name}", f"FOG floor, {raw_unit.name}",
              f"Floor-corrected, {corr_unit.name}")
    notes = ["Raw: 'value ± U' only when value − U lies above the FOG floor; otherwise "
             "'< L', L = value + U, never below the floor (docs/method.md D2: no value or U "
             "is printed below its floor)."]
    bw = {b for r in rates if (b := num(r.bandwidth_hz)) is not None}
    if bw:
        notes.append("At the FOG's output bandwidth: "
                     + ", ".join(f"{b:g} Hz" for b in sorted(bw)) + ".")
    sources = {src for r in rates if (src := r.intra.floor_source)}
    if (floor is not None and floor.stated) or sources:
        noise = num(floor.noise_dps) if floor is not None else None
        text = "FOG noise floor from " + (", ".join(sorted(sources)) if sources else
                                          (floor.source if floor is not None and floor.source
                                           is not None else "a record at rest"))
        if noise is not None:
            text += f"; {format_sig(noise, 3)} °/s per sample"
        if floor is not None and (duration_s := num(floor.duration_s)) is not None:
            text += f", {duration_s:g} s record at rest"
        notes.append(text + ". Floor-corrected = √(raw² − floor²), its interval from a "
                            "JCGM 101 Monte Carlo of the two variances (docs/method.md A5): "
                            "± U when the interval's lower end (2.5 %) is above zero, "
                            "otherwise '< L', L the square root of the difference's 97.5 % "
                            "quantile." + _mc_inputs(rates))
    if approx:
        notes.append("* U of the raw value from 2s/√(2(n−1)) over its n samples, assuming "
                     "independent samples; the result did not carry it.")
    blocks: list[Block] = [Table(header, tuple(rows), widths=(1.1, 2.0, 1.4, 2.2),
                               align="rrrr", caption=f"Axis {axis}: intra-turn instability "
                               "std(Δω_rand)/|ω_set| (docs/method.md A5)", notes=tuple(notes))]
    blocks += _stability_blocks(axis, rates)
    return blocks


def _mc_inputs(rates: Sequence[RateEntry]) -> str:
    """The Monte Carlo's inputs besides the printed raw and floor (docs/method.md A5), so
    the floor-corrected figure can be recomputed: each variance drawn as s² ν / χ²_ν."""
    raw = [d for r in rates if (d := num(r.intra.raw_dof)) is not None]
    floor = [d for r in rates if (d := num(r.intra.floor_dof)) is not None]
    draws = {d for r in rates if (d := num(r.intra.mc_draws)) is not None}
    if not raw or not floor or len(draws) != 1:
        return ""

    def span(xs: list[float]) -> str:
        lo, hi = min(xs), max(xs)
        return f"{lo:.0f}" if round(lo) == round(hi) else f"{lo:.0f} to {hi:.0f}"

    return (f" Its inputs: ν_raw = samples − fitted parameters = {span(raw)}, ν_floor = "
            f"2/3 of the floor's successive differences = {span(floor)}; each variance drawn "
            f"as s²·ν/χ²_ν, {min(draws):.0f} draws.")


def _stability_blocks(axis: str, rates: Sequence[RateEntry]) -> list[Block]:
    """Rate stability over an angle, as a datasheet states it (docs/method.md A5): over 1° and
    10° from the FOG (with what this FOG can verify), over 360° from the counter's
    per-turn rates, whose timing floor is far below the FOG's."""
    rows = []
    limited = False
    for r in rates:
        for a in _averaged(r):
            if a.angle_deg >= 360.0:
                continue   # one turn: the counter's σ below
            unit = PPM
            # docs/method.md D2: resolved, its interval; else '< L'
            own = (present(a.corrected, None, unit.scale, resolved=True,
                           interval=(a.lower, a.upper)).text
                   if a.resolved and a.corrected is not None and a.upper is not None
                   and a.lower is not None else
                   present(a.corrected, None, unit.scale, resolved=False, upper=a.upper).text)
            limited |= not a.resolved
            # docs/method.md D2: the measured figure against the FOG's floor over the same
            # window: 'raw ± U' only when raw - U > floor, else '< L' (never below the floor)
            measured = (present(a.raw, a.u, unit.scale, floor=a.floor)
                        if a.measured_resolved is None else
                        present(a.raw, a.u, unit.scale, resolved=a.measured_resolved,
                                upper=a.measured_upper, floor=a.floor))
            limited |= not measured.resolved
            rows.append((rate_text(r.set_rate_dps), f"{a.angle_deg:g}", "FOG",
                         measured.text + ("*" if a.u_approx and measured.resolved else ""),
                         format_sig(a.floor * unit.scale, 2) if a.floor is not None else "—",
                         own, format_sig(a.sensitivity * unit.scale, 2)
                         if a.sensitivity is not None else "—", text_of(a.blocks)))
        s, (iu, approx) = num(r.rate_instability_rel), _instability_u(r)
        if s is not None:
            unit = PPM
            # docs/method.md D2: σ of the per-turn rates as its chi-square interval, or
            # '< L' when it is not resolved above the timing floor (never below it)
            sigma = sigma_presented(r, iu, unit.scale)
            floor = num(r.rate_instability_floor_rel)
            rows.append((rate_text(r.set_rate_dps), "360", "counter",
                         sigma.text + ("*" if approx and sigma.resolved else ""),
                         format_sig(floor * unit.scale, 2) if floor is not None else "—",
                         sigma.text,
                         format_sig(floor * unit.scale, 2) if floor is not None else "—",
                         text_of(r.turns)))
    if not rows:
        return []
    approx_note = ["* U from 2s/√(2(n−1)) over the n windows (turns); the result did not "
                   "carry it."] if any(r[3].endswith("*") for r in rows) else []
    notes = ["Rate stability over an angle: the standard deviation of the table rate averaged "
             "over consecutive windows of that angle, relative to |ω_set|, as a rate-table "
             "datasheet states it. Over 1° and 10° it comes from the FOG (floor: the FOG's own "
             "noise averaged over the window; table's own = √(measured² − floor²)); over 360° "
             "from the counter's per-turn rates (σ of eq. 2; floor: the timing floor).",
             "Measured over 1° and 10° (FOG): 'value ± U' when value − U lies above the "
             "FOG's floor over the same window, else '< L', L = value + U, never below the "
             "floor (docs/method.md D2: no value or U is printed below its floor).",
             "Capability: 'smallest verifiable' is the smallest table figure this measurement "
             "could show as resolved, (8/(n − 1))^¼ × measured for n windows, or the "
             "counter's timing floor. A datasheet figure below it cannot be verified with "
             "this FOG or counter; '< L' states only that the table is within L.",
             *approx_note]
    return [Table(("Set rate, °/s", "Window, °", "From", "Measured, ppm", "Floor, ppm",
                   "Table's own, ppm", "Smallest verifiable, ppm", "Windows"), tuple(rows),
                  widths=(1.0, 0.8, 0.8, 1.8, 0.9, 1.6, 1.2, 0.8),
                  align="rrlrrrrr",
                  caption=f"Axis {axis}: rate stability over 1°, 10° and 360° (docs/method.md A5)",
                  notes=tuple(notes))]


def _across_axes(axes: Mapping[str, LadderAxis]) -> list[Block]:
    rates = {a: ax.rates for a, ax in axes.items()}
    blocks: list[Block] = []
    amp_unit = rel_unit(*[num(h.amplitude_rel) for rr in rates.values() for r in rr
                          for h in r.harmonics])
    blocks += figure_of("Once-per-revolution amplitude vs rate, relative and absolute "
                      "(cf. paper fig. 7)",
                      plots.one_rev, rates, amp_unit.scale, amp_unit.name)
    unit = rel_unit(*[num(r.intra_turn_instability_rel) for rr in rates.values() for r in rr])
    blocks += figure_of("Intra-turn instability vs rate, raw and floor-corrected "
                      "(cf. paper fig. 10)",
                      plots.intra_turn, rates, unit.scale, unit.name)
    blocks += figure_of("FOG scale k and bias ω0 per ± pair (docs/method.md A3)",
                      plots.pairs, {a: ax.pairs for a, ax in axes.items()})
    blocks += figure_of("Allan deviation of the FOG at rest: its noise floor (docs/method.md A5)",
                      plots.allan, {a: ax.noise_floor for a, ax in axes.items()
                                    if ax.noise_floor is not None and ax.noise_floor.stated},
                      width_frac=0.8)
    return blocks


def _per_turn_annex(src: Sources) -> tuple[Block, ...]:
    rows = []
    for axis, r in _ladder(src).rates():
        w_set = num(r.set_rate_dps)
        cr = [num(x) for x in r.counter_rate_dps]
        if not w_set or not cr:
            continue
        dev = ", ".join(format_sig(((x or math.nan) / w_set - 1) * 1e6, 3, signed=True)
                        .replace("n/a", "—") for x in cr)
        rows.append((axis, rate_text(w_set), dev))
    return (Table(("Axis", "Set rate, °/s", "Per-turn rate deviations (ω_i/ω_set − 1), ppm, "
                   "in turn order"), tuple(rows), widths=(0.9, 1.1, 6.0), align="lrl",
                  caption="Per-turn counter rates (docs/method.md A1), relative to the set rate"),)

