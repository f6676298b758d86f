"""The rate ladder's result model: what result.json's `axes` body holds (CONTRACT §3), as
msgspec Structs (issue 60), the one module that spells its keys.

Why a model: the analysis (analysis.py) builds it from its typed values, result.json's
`axes` body is its encoding, and the certificate, the DCC, the records and the station
decode it once (codec.py) and read attributes, so every key is a field spelled here and
nowhere else, and msgspec, not code of ours, checks a body against it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, cast

import msgspec
from msgspec import UNSET, UnsetType

from bench.report.budget import Budget, BudgetRecord
from bench.report.conformity import Check as Judged
from bench.report.result_frame import (
    MalformedResult,
    ResultFrame,
)
from drivers.json_types import JsonValue
from drivers.units import SECONDS_PER_HOUR

if TYPE_CHECKING:
    # the builders' inputs, for their hints only: the readers (certificate, records,
    # station) load this module without the analysis and numpy
    from bench.analysis.allan import AllanCurve
    from bench.analysis.crosscal import CrossCalibration, HalfMean
    from bench.analysis.random_part import AveragedInstability, RandomPartResult
    from bench.analysis.results import PairResult, RateResult, SystematicResult
    from bench.analysis.systematic import HarmonicResult, MainsResult
    from bench.analysis.systematic import NoiseInflation as NoiseInflation_
    from bench.analysis.turns import CounterBudget, TurnsResult
    from procedures.rate_ladder.conditions import AxisTemperature

    #: the analysis's values the builders take fields from by name (`_named`)
    Analysed = (TurnsResult | CounterBudget | HarmonicResult | MainsResult | NoiseInflation_
                | SystematicResult | RandomPartResult | AveragedInstability | HalfMean
                | CrossCalibration)

__all__ = ["Half", "Harmonic", "IntraTurn", "LadderAxis", "LadderCheck", "LadderResult",
           "Mains", "MalformedResult", "NoiseFloor", "PairEntry", "RateEntry"]

#: the checked quantities that are standard deviations (magnitudes: printed without a
#: sign on the certificate; one-sided, with no lower limit, in the DCC)
UNSIGNED = frozenset({"rate_instability", "intra_turn_instability",
                      "intra_turn_instability_corrected"})


# -- the model ---------------------------------------------------------------------------------
#
# msgspec Structs (issue 60), as the drift kind's (procedures/drift_pulse/result.py): each
# Struct's field order is its entry's key order in result.json, so the file's bytes are the
# model's encoding (codec.py). Uncertainty names (bench/report/uncertainty_names.py): the `_u`
# keys CONTRACT §3 binds are kept, and their explicit twin (`_U` expanded, `_ustd` standard)
# is a field of its own beside them, so no key is derived by a rule over names. Every field
# has a default: a hand-made or older result (sample.py) states fewer keys, and its readers
# say "not stated"; an older result's missing twin is its `_u` key's value (`_twins`), a
# body whose twins differ is refused.

#: a value of bench.analysis.results.judge_rate's judgement
Judgement = str | int | float | bool | None


class _Model(msgspec.Struct, frozen=True, kw_only=True):
    """A part of the ladder's body; `TWINS` pairs each `_u` field with its explicit twin."""

    TWINS: ClassVar[tuple[tuple[str, str], ...]] = ()

    def __post_init__(self) -> None:
        for key, twin in self.TWINS:
            value, stated = getattr(self, key), getattr(self, twin)
            if stated is None or stated is UNSET:
                if value is not None and value is not UNSET:
                    msgspec.structs.force_setattr(self, twin, value)
            elif value is not None and value is not UNSET and value != stated:
                raise ValueError(f"`{twin}` {stated!r} differs from `{key}` {value!r}, "
                                 "its twin")


class RateErrorBudget(_Model, frozen=True, kw_only=True):
    """What eq. 1's U rests on (docs/method.md A1-A2, D1): standard uncertainties."""

    TWINS = (("timing_u_rel", "timing_ustd_rel"), ("timebase_u_rel", "timebase_ustd_rel"),
             ("repeatability_u_rel", "repeatability_ustd_rel"),
             ("timestamp_u_s", "timestamp_ustd_s"), ("edge_u_s", "edge_ustd_s"),
             ("time_tie_u_s", "time_tie_ustd_s"), ("period_u_s", "period_ustd_s"),
             ("timebase_correction_u_rel", "timebase_correction_ustd_rel"))

    timing_u_rel: float | None = None
    timing_ustd_rel: float | None = None
    timebase_u_rel: float | None = None
    timebase_ustd_rel: float | None = None
    repeatability_u_rel: float | None = None
    repeatability_ustd_rel: float | None = None
    repeatability_basis: str | None = None
    repeatability_dof: float | None = None
    dof_eff: float | None = None
    coverage_factor: float | None = None
    timestamp_u_s: float | None = None
    timestamp_ustd_s: float | None = None
    trigger_jitter_s: float | None = None
    timebase_limit_rel: float | None = None
    edge_u_s: float | None = None
    edge_ustd_s: float | None = None
    time_tie_u_s: float | None = None
    time_tie_ustd_s: float | None = None
    period_u_s: float | None = None
    period_ustd_s: float | None = None
    # an applied time-base correction's e and u(e) (issue 58): absent without one
    timebase_correction_rel: float | UnsetType = UNSET
    timebase_correction_u_rel: float | UnsetType = UNSET
    timebase_correction_ustd_rel: float | UnsetType = UNSET


class Harmonic(_Model, frozen=True, kw_only=True):
    """One harmonic of the rate along the turn (docs/method.md A2, A4)."""

    TWINS = (("amplitude_u_rel", "amplitude_U_rel"), ("phase_u_deg", "phase_U_deg"))

    order: int | None = None
    amplitude_rel: float | None = None
    amplitude_u_rel: float | None = None
    amplitude_U_rel: float | None = None        # noqa: N815
    phase_deg: float | None = None
    phase_u_deg: float | None = None
    phase_U_deg: float | None = None            # noqa: N815
    detected: bool | None = None                # None: an older result, which did not say
    amplitude_upper_rel: float | None = None    # L = a + c u(a), undetected (A4, D2)
    interval_factor: float | None = None        # c = sqrt(-2 ln alpha_1) (A4)


class Mains(_Model, frozen=True, kw_only=True):
    """The rate's ripple at the mains frequency (docs/method.md A2, A4)."""

    TWINS = (("amplitude_u_dps", "amplitude_U_dps"), ("phase_u_deg", "phase_U_deg"))

    frequency_hz: float | None = None
    amplitude_dps: float | None = None
    amplitude_u_dps: float | None = None
    amplitude_U_dps: float | None = None        # noqa: N815
    phase_deg: float | None = None
    phase_u_deg: float | None = None
    phase_U_deg: float | None = None            # noqa: N815
    detected: bool | None = None
    significance_chi2: float | None = None
    source: str | None = None
    amplitude_upper_dps: float | None = None    # L = a + c u(a), undetected (A4, D2)
    interval_factor: float | None = None

    @property
    def stated(self) -> bool:
        """The result states the tone (an empty `mains` states nothing)."""
        return self != Mains()


class Binned(_Model, frozen=True, kw_only=True):
    """The paper's binned average by angle (docs/method.md A4)."""

    bin_deg: float | None = None
    centres_deg: tuple[float | None, ...] = ()
    deviation_rel: tuple[float | None, ...] = ()
    u_rel: tuple[float | None, ...] = ()       # per bin, as the analysis states it
    peak_to_peak_rel: float | None = None


class NoiseInflation(_Model, frozen=True, kw_only=True):
    """The block-variance check of the FOG's noise and the factor applied (docs/method.md A3)."""

    block_deg: float | None = None
    blocks: int | None = None
    ratio: float | None = None
    applied: float | None = None


class Systematic(_Model, frozen=True, kw_only=True):
    """The systematic intra-turn rate (docs/method.md A4): `rates[].systematic`."""

    harmonics: tuple[Harmonic, ...] = ()
    mains: Mains | None = None
    binned: Binned | None = None
    residual_std_dps: float | None = None
    noise_inflation: NoiseInflation | None = None
    detection: dict[str, str | int | float] = msgspec.field(default_factory=dict)  # the rule


class Averaged(_Model, frozen=True, kw_only=True):
    """The random part averaged over an angle (docs/method.md A5)."""

    TWINS = (("u_rel", "U_rel"),)

    angle_deg: float | None = None
    instability_rel: float | None = None
    u_rel: float | None = None
    U_rel: float | None = None                  # noqa: N815
    floor_rel: float | None = None
    corrected_rel: float | None = None
    corrected_upper_rel: float | None = None
    corrected_lower_rel: float | None = None
    resolved: bool | None = None
    corrected_ustd_rel: float | None = None
    ustd_rel: float | None = None
    measured_resolved: bool | None = None
    measured_upper_rel: float | None = None
    interval_level: float | None = None
    dof: int | float | None = None
    blocks: int | None = None
    samples_per_block: float | None = None


class IntraTurn(_Model, frozen=True, kw_only=True):
    """The random intra-turn rate and its floor-corrected interval (docs/method.md A5):
    `rates[].intra_turn`."""

    TWINS = (("corrected_u_rel", "corrected_U_rel"),)

    instability_rel: float | None = None
    floor_rel: float | None = None
    floor_source: str | None = None
    corrected_rel: float | None = None
    corrected_upper_rel: float | None = None
    corrected_lower_rel: float | None = None
    corrected_u_rel: float | None = None
    corrected_U_rel: float | None = None        # noqa: N815
    interval_level: float | None = None
    interval_method: str | None = None
    floor_dof: float | None = None
    resolved: bool | None = None
    raw_resolved: bool | None = None            # the raw figure above the FOG floor (D2)
    raw_upper_rel: float | None = None          # L of the raw figure, not resolved (D2)
    raw_ustd_rel: float | None = None
    raw_dof: float | None = None
    mc_draws: int | None = None
    corrected_ustd_rel: float | None = None
    bandwidth_hz: float | None = None
    std_dps: float | None = None
    samples: int | None = None
    averaged: tuple[Averaged, ...] = ()         # over 1/10/360 deg


class LadderCheck(Judged, _Model, frozen=True, kw_only=True):
    """One conformity check of a rate (bench/report/conformity.py's, docs/method.md A6), as
    `checks[]` and the rate's own `checks[]` hold it; an unresolved value's floor and a
    resolved sigma's lower limit only where they apply."""

    TWINS = (("u_rel", "U_rel"),)

    lower_rel: float | None | UnsetType = UNSET
    floor_rel: float | UnsetType = UNSET
    floor_name: str | UnsetType = UNSET

    @classmethod
    def of(cls, c: Judged) -> LadderCheck:
        """A judgement (bench/report/conformity.py) as the result states it."""
        return cls(**msgspec.structs.asdict(c))


class RateEntry(_Model, frozen=True, kw_only=True):
    """One commanded rate and direction (docs/method.md A1-A5): `axes.<axis>.rates[]`."""

    TWINS = (("rate_error_u_rel", "rate_error_U_rel"),
             ("intra_turn_instability_u_rel", "intra_turn_instability_U_rel"),
             ("intra_turn_instability_corrected_u_rel", "intra_turn_instability_corrected_U_rel"),
             ("rate_instability_u_rel", "rate_instability_U_rel"))

    set_rate_dps: float
    turns: int | None = None
    counter_rate_dps: tuple[float | None, ...] = ()   # per turn, in turn order (A1)
    mean_rate_dps: float | None = None
    rate_error_rel: float | None = None
    rate_error_u_rel: float | None = None
    rate_error_U_rel: float | None = None                        # noqa: N815
    rate_instability_rel: float | None = None
    rate_instability_floor_rel: float | None = None
    rate_error_budget: RateErrorBudget | None = None
    intra_turn_instability_rel: float | None = None
    intra_turn_instability_corrected_rel: float | None = None
    intra_turn_instability_u_rel: float | None = None
    intra_turn_instability_U_rel: float | None = None            # noqa: N815
    intra_turn_instability_corrected_u_rel: float | None = None
    intra_turn_instability_corrected_U_rel: float | None = None  # noqa: N815
    systematic: Systematic = msgspec.field(default_factory=Systematic)
    intra_turn: IntraTurn = msgspec.field(default_factory=IntraTurn)
    windows: tuple[dict[str, int | float], ...] = ()       # the timed windows
    judgement: dict[str, Judgement] | UnsetType = UNSET   # bench.analysis judge_rate's
    rate_instability_u_rel: float | None = None
    rate_instability_U_rel: float | None = None                  # noqa: N815
    rate_instability_ustd_rel: float | None = None
    rate_instability_upper_rel: float | None = None
    rate_instability_lower_rel: float | None = None
    rate_instability_resolved: bool | None = None
    session: int | None = None
    fog_lost_frames: int | None = None
    checks: tuple[LadderCheck, ...] = ()
    verdict: str | None = None
    budgets: tuple[BudgetRecord, ...] = ()

    @property
    def mains(self) -> Mains | None:
        return self.systematic.mains

    @property
    def harmonics(self) -> tuple[Harmonic, ...]:
        return self.systematic.harmonics

    @property
    def binned(self) -> Binned | None:
        return self.systematic.binned

    @property
    def intra(self) -> IntraTurn:
        return self.intra_turn

    @property
    def bandwidth_hz(self) -> float | None:
        return self.intra_turn.bandwidth_hz

    @property
    def averaged(self) -> tuple[Averaged, ...]:
        return self.intra_turn.averaged

    def budget(self, key: str) -> Budget | None:
        """The budget of result key `key` (`rate_error_rel`...), None if none states it."""
        return next((b.budget() for b in self.budgets if b.key == key), None)


class Half(_Model, frozen=True, kw_only=True):
    """One half of a +/- pair (docs/method.md A3): the counter's and the FOG's mean rates."""

    TWINS = (("fog_mean_u_dps", "fog_mean_ustd_dps"),
             ("counter_mean_u_dps", "counter_mean_ustd_dps"))

    sign: int | None = None
    turns: int | None = None
    t_centre_s: float | None = None
    fog_mean_dps: float | None = None
    fog_mean_u_dps: float | None = None
    fog_mean_ustd_dps: float | None = None
    counter_mean_dps: float | None = None
    counter_mean_u_dps: float | None = None
    counter_mean_ustd_dps: float | None = None


class PairEntry(_Model, frozen=True, kw_only=True):
    """One +/- pair's FOG cross-calibration (docs/method.md A3, eq. 5-6): `axes.<axis>.pairs[]`."""

    TWINS = (("k_u", "k_U"), ("w0_u_dps", "w0_U_dps"),
             ("drift_u_dps_per_h", "drift_U_dps_per_h"))

    rate_dps: float
    k: float | None = None
    k_u: float | None = None
    k_U: float | None = None                    # noqa: N815
    w0_dps: float | None = None
    w0_u_dps: float | None = None
    w0_U_dps: float | None = None               # noqa: N815
    w0_t_ref_s: float | None = None             # the time w0 is referred to
    drift_dps_per_h: float | None = None
    drift_u_dps_per_h: float | None = None
    drift_U_dps_per_h: float | None = None      # noqa: N815
    method: str | None = None                   # how k and w0 were found
    drift_source: str | None = None             # where the bias drift during the pair comes from
    k_eq5: float | None = None
    chi2: float | None = None
    dof: int | None = None
    birge_ratio: float | None = None
    halves: tuple[Half, ...] = ()
    noise_inflation: NoiseInflation | None = None
    half_sessions: tuple[int, ...] = ()         # a resumed pair: each half's session
    bias_model: str = ""
    budgets: tuple[BudgetRecord, ...] = ()


class NoiseFloor(_Model, frozen=True, kw_only=True):
    """The FOG at rest (docs/method.md A5): its Allan deviation and bias."""

    source: str | None = None
    samples: int | None = None
    duration_s: float | None = None
    sample_std_dps: float | None = None
    mean_dps: float | None = None               # bias at rest (bench control)
    allan_tau_s: tuple[float, ...] = ()
    allan_dev_dps: tuple[float, ...] = ()

    @property
    def stated(self) -> bool:
        """The result states the record at rest (an empty `noise_floor` states nothing)."""
        return self != NoiseFloor()

    @property
    def noise_dps(self) -> float | None:
        """The FOG's noise per sample."""
        return self.sample_std_dps


class LadderAxis(_Model, frozen=True, kw_only=True):
    """One axis of the ladder: its rates, its pairs and its FOG's noise floor."""

    rates: tuple[RateEntry, ...] = ()
    pairs: tuple[PairEntry, ...] = ()
    noise_floor: NoiseFloor | None = None


class FogTemperature(msgspec.Struct, frozen=True, kw_only=True):
    """The FOG's temperature per axis, from its frames (conditions.py measures it)."""

    source: str = ("FOG frames' temperature field (table top, at the FOG), deg C, integer "
                   "resolution")
    axes: Mapping[str, AxisTemperature]


class ConditionsMeasured(msgspec.Struct, frozen=True):
    """What the bench measured of the conditions itself (`conditions_measured`)."""

    fog_temperature: FogTemperature | None
    room: None = None       # no sensor on this stand: not measured


class LadderBody(msgspec.Struct, frozen=True, kw_only=True):
    """What a ladder's result.json holds after the frame, in its key order: the axes, the
    corrections applied (issue 58; absent: none), what the bench measured itself."""

    axes: dict[str, LadderAxis]
    corrections: JsonValue | UnsetType = UNSET     # as the corrections file states them
    conditions_measured: ConditionsMeasured | UnsetType = UNSET


@dataclass(frozen=True, slots=True)
class LadderResult:
    """A rate-ladder run's result.json: the shared frame and the axes, decoded once
    (codec.py)."""

    frame: ResultFrame
    axes: dict[str, LadderAxis]

    def rates(self) -> list[tuple[str, RateEntry]]:
        """Every (axis, rate entry), in the result's order."""
        return [(name, r) for name, a in self.axes.items() for r in a.rates]

    def pairs(self) -> list[tuple[str, PairEntry]]:
        return [(name, p) for name, a in self.axes.items() for p in a.pairs]


# -- building: the analysis's typed values as the model ----------------------------------------
#
# The analysis (bench/analysis, procedures/rate_ladder/analysis.py) computes typed values and
# never spells a key; the functions below place them in the model, whose encoding (codec.py)
# is CONTRACT §3's `axes.<axis>.rates[]`, `pairs[]` and `noise_floor`, in the order result.json
# has always had them. Non-finite numbers are written as null (codec.py: JSON has no NaN).

def _named(cls: type[_Model], *sources: Analysed, but: tuple[str, ...] = ()) -> dict[str, Any]:
    """Each field of `cls` that one of `sources` holds under the same name (the analysis
    names its values as result.json does), the last source's winning, none of `but`; each
    `_u` field's twin is then filled by `_Model`."""
    return {f: getattr(s, f) for s in sources for f in cls.__struct_fields__
            if f not in but and hasattr(s, f)}


def rate_error_budget(tr: TurnsResult) -> RateErrorBudget:
    """Eq. 1's budget (docs/method.md A1-A2, D1): the counter chain's timing terms, the
    time base as the counter's budget states it; an applied time-base correction's e and
    u(e) only when one was applied (issue 58)."""
    b = tr.budget
    if b.timebase_correction_u_rel > 0.0 or b.timebase_correction_rel != 0.0:
        return RateErrorBudget(**_named(RateErrorBudget, tr, b))
    return RateErrorBudget(**_named(RateErrorBudget, tr, b, but=(
        "timebase_correction_rel", "timebase_correction_u_rel")))


def harmonic(h: HarmonicResult) -> Harmonic:
    return Harmonic(**_named(Harmonic, h))


def mains(m: MainsResult) -> Mains:
    return Mains(**_named(Mains, m), significance_chi2=m.significance)


def inflation(n: NoiseInflation_) -> NoiseInflation:
    return NoiseInflation(**_named(NoiseInflation, n), applied=n.factor)


def systematic(s: SystematicResult) -> Systematic:
    """The systematic intra-turn rate (docs/method.md A4)."""
    b = s.binned
    return Systematic(harmonics=tuple(harmonic(h) for h in s.harmonics),
                      mains=mains(s.mains) if s.mains else None,
                      binned=Binned(bin_deg=b.bin_deg, centres_deg=tuple(b.centres_deg),
                                    deviation_rel=tuple(b.deviation_rel), u_rel=tuple(b.u_rel),
                                    peak_to_peak_rel=b.peak_to_peak_rel),
                      residual_std_dps=s.residual_std_dps,
                      noise_inflation=inflation(s.inflation), detection=dict(s.detection))


def intra_turn(r: RandomPartResult) -> IntraTurn:
    """The random intra-turn rate and its floor-corrected interval, and the random part
    averaged over angles (docs/method.md A5)."""
    from bench.analysis.random_part import LEVEL, MC_DRAWS

    return IntraTurn(
        **_named(IntraTurn, r, but=("averaged",)), interval_level=LEVEL,
        interval_method="JCGM 101 Monte Carlo of raw^2 - floor^2 (scaled inverse "
                        "chi-square per variance)", mc_draws=MC_DRAWS,
        averaged=tuple(Averaged(**_named(Averaged, a), interval_level=LEVEL)
                       for a in r.averaged))


def turns_entry(tr: TurnsResult) -> RateEntry:
    """Eq. 1-2 of one direction: the per-turn rates, the rate error and its budget, the
    rate instability and its timing floor (docs/method.md A1-A2)."""
    return RateEntry(**_named(RateEntry, tr), rate_error_budget=rate_error_budget(tr))


def rate_entry(r: RateResult) -> RateEntry:
    """One commanded rate and direction (docs/method.md A1-A5) as the analysis measured it,
    without what the ladder adds after judging it (analysis.py `judged`)."""
    entry = msgspec.structs.replace(
        turns_entry(r.turns_result),
        intra_turn_instability_rel=r.random.instability_rel,
        intra_turn_instability_corrected_rel=r.random.corrected_rel,
        # docs/method.md A5: U of a std from the record's samples (white random part assumed)
        intra_turn_instability_u_rel=r.random.raw_U_rel,
        # docs/method.md A5: the corrected figure's U only when it is resolved (JCGM 101);
        # otherwise it is stated as '< intra_turn.corrected_upper_rel'
        intra_turn_instability_corrected_u_rel=r.random.corrected_u_rel,
        systematic=systematic(r.systematic), intra_turn=intra_turn(r.random),
        windows=tuple(dict(w) for w in r.windows))
    if r.verdict is None:
        return entry
    # judged by bench.analysis.results.judge_rate (its judgement's values are plain)
    return msgspec.structs.replace(entry, verdict=r.verdict, judgement=cast(
        "dict[str, Judgement]", dict(r.judgement or {})))


def pair_entry(p: PairResult) -> PairEntry:
    """One +/- pair's FOG cross-calibration (docs/method.md A3, eq. 5-6): k, w0 (at t_ref)
    and the bias drift with U."""
    c = p.cal
    return PairEntry(**_named(PairEntry, c, but=("halves",)), rate_dps=p.rate_dps,
                     w0_t_ref_s=c.t_ref_s, drift_dps_per_h=c.drift_dps_per_s * SECONDS_PER_HOUR,
                     drift_u_dps_per_h=c.drift_u_dps_per_s * SECONDS_PER_HOUR,
                     halves=tuple(Half(**_named(Half, h)) for h in c.halves),
                     noise_inflation=inflation(p.noise_inflation),
                     half_sessions=tuple(p.sessions), bias_model=p.bias_model)


def noise_floor(samples: int, duration_s: float, sample_std_dps: float, mean_dps: float,
                curve: AllanCurve) -> NoiseFloor:
    """The FOG at rest (docs/method.md A5): `axes.<axis>.noise_floor`."""
    return NoiseFloor(source="Allan deviation of a static FOG record", samples=samples,
                      duration_s=duration_s, sample_std_dps=sample_std_dps,
                      mean_dps=mean_dps, allan_tau_s=tuple(curve.tau_s),
                      allan_dev_dps=tuple(curve.adev))
