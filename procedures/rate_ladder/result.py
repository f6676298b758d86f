"""The rate ladder's result.json, typed: the one module that spells its keys (CONTRACT §3).

`LadderResult.from_json` reads a result.json (refusing a malformed one, naming the key
path), `LadderResult.conform` reads it leniently for the certificate (a malformed
container dropped and named, the rest kept), `to_json` gives the document back byte for
byte as `bench analyze` writes it (keys in their order, numbers as they were). Readers
(certificate, DCC, records, station, summary) take attributes from here; the writer at the
end (`rate_json`, `pair_json`, `noise_floor_json`) lays the analysis's typed values out
under the same keys, so a key is renamed here or nowhere.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypedDict

from bench.core import rundir_layout as layout
from bench.report.result_frame import (
    Issues,
    JsonObject,
    JsonValue,
    KeyPath,
    MalformedResult,
    ResultFrame,
    as_object,
    conform_each,
    conform_frame,
    conform_list,
    conform_object,
    conform_plain_list,
    flag,
    integer,
    number,
    obj,
    objects,
    text,
)
from drivers.units import SECONDS_PER_HOUR

if TYPE_CHECKING:
    # the writer's inputs, for its hints only: the readers (certificate, records, station)
    # load this module without the analysis and numpy
    from bench.analysis.allan import AllanCurve
    from bench.analysis.crosscal import CrossCalibration, HalfMean
    from bench.analysis.random_part import AveragedInstability, RandomPartResult
    from bench.analysis.results import PairResult, RateResult, SystematicResult
    from bench.analysis.systematic import (
        BinnedSystematic,
        HarmonicResult,
        MainsResult,
        NoiseInflation,
    )
    from bench.analysis.turns import CounterBudget, TurnsResult

__all__ = ["Half", "Harmonic", "IntraTurn", "LadderAxis", "Mains", "LadderResult", "MalformedResult", "NoiseFloor", "PairEntry",
           "RateEntry", "add_budgets", "with_conditions_measured"]

#: the checked quantities that are standard deviations (magnitudes: printed without a
#: sign on the certificate; one-sided, with no lower limit, in the DCC)
UNSIGNED = frozenset({"rate_instability", "intra_turn_instability",
                      "intra_turn_instability_corrected"})


# -- the containers' checks (what the certificate may safely walk) ----------------------------

def _conform_systematic(doc: JsonObject, path: KeyPath, issues: Issues) -> JsonObject:
    # a harmonic means nothing without its order
    conform_list(doc, "harmonics", path, issues, numeric="order")
    conform_object(doc, "mains", path, issues)
    conform_object(doc, "binned", path, issues)
    return doc


def _conform_intra_turn(doc: JsonObject, path: KeyPath, issues: Issues) -> JsonObject:
    conform_list(doc, "averaged", path, issues)
    return doc


def _conform_rate(doc: JsonObject, path: KeyPath, issues: Issues) -> JsonObject:
    conform_object(doc, "systematic", path, issues, _conform_systematic)
    conform_object(doc, "intra_turn", path, issues, _conform_intra_turn)
    conform_plain_list(doc, "counter_rate_dps", path, issues)
    return doc


def _conform_axis(doc: JsonObject, path: KeyPath, issues: Issues) -> JsonObject:
    # a rate without its set rate, a pair without its rate mean nothing
    conform_list(doc, "rates", path, issues, _conform_rate, numeric="set_rate_dps")
    conform_list(doc, "pairs", path, issues, numeric="rate_dps")
    conform_object(doc, "noise_floor", path, issues)
    return doc


def _conform_axes(doc: JsonObject, path: KeyPath, issues: Issues) -> JsonObject:
    return conform_each(doc, path, issues, _conform_axis)


def conform_ladder(doc: JsonObject, issues: Issues) -> JsonObject:
    """The ladder's part of a result.json checked, in place."""
    conform_object(doc, "axes", (), issues, _conform_axes)
    return doc


# -- the typed result -----------------------------------------------------------------------

class _Phase(TypedDict):
    """A fitted tone's phase and whether its amplitude was detected (docs/method.md A4)."""

    phase_deg: float | None
    phase_u_deg: float | None
    detected: bool | None      # None: an older result, which did not say


def _expanded(doc: JsonObject, key_U: str, key_u: str) -> float | None:
    """An expanded uncertainty as result.json writes it (`_U_`), or an older result's
    `_u_` spelling of it."""
    return number(doc, key_U) if key_U in doc else number(doc, key_u)


def _phase(doc: JsonObject) -> _Phase:
    return {"phase_deg": number(doc, "phase_deg"), "phase_u_deg": number(doc, "phase_u_deg"),
            "detected": flag(doc, "detected")}


@dataclass(frozen=True, slots=True)
class Harmonic:
    """One harmonic of the rate along the turn (docs/method.md A2)."""

    order: float | None
    amplitude_rel: float | None
    amplitude_u_rel: float | None
    phase_deg: float | None
    phase_u_deg: float | None
    detected: bool | None
    doc: JsonObject

    @property
    def amplitude_U_rel(self) -> float | None:
        return _expanded(self.doc, "amplitude_U_rel", "amplitude_u_rel")

    @property
    def phase_U_deg(self) -> float | None:
        return _expanded(self.doc, "phase_U_deg", "phase_u_deg")

    @property
    def amplitude_upper_rel(self) -> float | None:
        """L = a + c u(a), the limit of an undetected harmonic (docs/method.md A4, D2)."""
        return number(self.doc, "amplitude_upper_rel")

    @property
    def interval_factor(self) -> float | None:
        """c = sqrt(-2 ln alpha_1) of the tone's interval a +/- c u(a) (A4)."""
        return number(self.doc, "interval_factor")


@dataclass(frozen=True, slots=True)
class Mains:
    """The rate's ripple at the mains frequency (docs/method.md A2)."""

    frequency_hz: float | None
    amplitude_dps: float | None
    amplitude_u_dps: float | None
    phase_deg: float | None
    phase_u_deg: float | None
    detected: bool | None
    doc: JsonObject

    @property
    def amplitude_upper_dps(self) -> float | None:
        """L = a + c u(a), the limit of an undetected tone (docs/method.md A4, D2)."""
        return number(self.doc, "amplitude_upper_dps")

    @property
    def interval_factor(self) -> float | None:
        """c = sqrt(-2 ln alpha_1) of the tone's interval a +/- c u(a) (A4)."""
        return number(self.doc, "interval_factor")


@dataclass(frozen=True, slots=True)
class IntraTurn:
    """The intra-turn instability's details (docs/method.md A5): `rates[].intra_turn`."""

    samples: float | None
    floor_rel: float | None
    floor_source: str | None
    corrected_upper_rel: float | None
    corrected_lower_rel: float | None
    resolved: bool | None
    bandwidth_hz: float | None
    averaged: JsonValue          # over 1/10/360 deg (bench.analysis.random_part's shape)
    doc: JsonObject

    @property
    def raw_resolved(self) -> bool | None:
        """The raw figure stands above the FOG floor (docs/method.md D2); None: older."""
        return flag(self.doc, "raw_resolved")

    @property
    def raw_upper_rel(self) -> float | None:
        """L of the raw figure when not resolved: raw + U, never below the floor (D2)."""
        return number(self.doc, "raw_upper_rel")

    @classmethod
    def from_json(cls, doc: JsonObject) -> IntraTurn:
        return cls(samples=number(doc, "samples"), floor_rel=number(doc, "floor_rel"),
                   floor_source=text(doc, "floor_source"),
                   corrected_upper_rel=number(doc, "corrected_upper_rel"),
                   corrected_lower_rel=number(doc, "corrected_lower_rel"),
                   resolved=flag(doc, "resolved"), bandwidth_hz=number(doc, "bandwidth_hz"),
                   averaged=doc.get("averaged"), doc=doc)


#: older results' names of `intra_turn.averaged` (read by the certificate)
AVERAGED_OLD_KEYS = ("instability_over_angle", "intra_turn_instability_over",
                     "averaged_instability")


@dataclass(frozen=True, slots=True)
class RateEntry:
    """One commanded rate and direction (docs/method.md A1-A5): `axes.<axis>.rates[]`."""

    set_rate_dps: float
    turns: int | None
    mean_rate_dps: float | None
    rate_error_rel: float | None
    rate_error_u_rel: float | None
    rate_instability_rel: float | None
    rate_instability_u_rel: float | None
    rate_instability_upper_rel: float | None
    rate_instability_lower_rel: float | None
    rate_instability_floor_rel: float | None
    rate_instability_resolved: bool | None
    intra_turn_instability_rel: float | None
    intra_turn_instability_u_rel: float | None
    intra_turn_instability_corrected_rel: float | None
    intra_turn_instability_corrected_u_rel: float | None
    session: int | None
    fog_lost_frames: int | None
    verdict: str | None
    systematic: JsonObject
    intra_turn: JsonObject
    budgets: tuple[JsonObject, ...]
    doc: JsonObject          # every key, in result.json's order

    @classmethod
    def from_json(cls, doc: JsonObject) -> RateEntry:
        rate = number(doc, "set_rate_dps")
        if rate is None:
            raise MalformedResult("rates[]", "has no numeric set_rate_dps")
        return cls(
            set_rate_dps=rate, turns=integer(doc, "turns"),
            mean_rate_dps=number(doc, "mean_rate_dps"),
            rate_error_rel=number(doc, "rate_error_rel"),
            rate_error_u_rel=number(doc, "rate_error_u_rel"),
            rate_instability_rel=number(doc, "rate_instability_rel"),
            rate_instability_u_rel=number(doc, "rate_instability_u_rel"),
            rate_instability_upper_rel=number(doc, "rate_instability_upper_rel"),
            rate_instability_lower_rel=number(doc, "rate_instability_lower_rel"),
            rate_instability_floor_rel=number(doc, "rate_instability_floor_rel"),
            rate_instability_resolved=flag(doc, "rate_instability_resolved"),
            intra_turn_instability_rel=number(doc, "intra_turn_instability_rel"),
            intra_turn_instability_u_rel=number(doc, "intra_turn_instability_u_rel"),
            intra_turn_instability_corrected_rel=number(
                doc, "intra_turn_instability_corrected_rel"),
            intra_turn_instability_corrected_u_rel=number(
                doc, "intra_turn_instability_corrected_u_rel"),
            session=integer(doc, "session"), fog_lost_frames=integer(doc, "fog_lost_frames"),
            verdict=text(doc, "verdict"), systematic=obj(doc, "systematic"),
            intra_turn=obj(doc, "intra_turn"), budgets=objects(doc, "budgets"), doc=doc)

    @property
    def mains(self) -> Mains | None:
        """The mains-frequency ripple's fit (docs/method.md A2), None when none."""
        m = as_object(self.systematic.get("mains"))
        if m is None:
            return None
        return Mains(frequency_hz=number(m, "frequency_hz"),
                     amplitude_dps=number(m, "amplitude_dps"),
                     amplitude_u_dps=number(m, "amplitude_u_dps"), **_phase(m), doc=m)

    @property
    def harmonics(self) -> tuple[Harmonic, ...]:
        return tuple(Harmonic(order=number(h, "order"), amplitude_rel=number(h, "amplitude_rel"),
                              amplitude_u_rel=number(h, "amplitude_u_rel"), **_phase(h), doc=h)
                     for h in objects(self.systematic, "harmonics"))

    @property
    def counter_rate_dps(self) -> tuple[JsonValue, ...]:
        """The per-turn counter rates as recorded (docs/method.md A1), in turn order."""
        v = self.doc.get("counter_rate_dps")
        return tuple(v) if isinstance(v, list) else ()

    @property
    def binned(self) -> JsonObject:
        """The paper's binned average by angle (docs/method.md A4), {} when none."""
        return obj(self.systematic, "binned")

    @property
    def rate_error_budget(self) -> JsonObject | None:
        return as_object(self.doc.get("rate_error_budget"))

    @property
    def judgement(self) -> JsonObject | None:
        return as_object(self.doc.get("judgement"))

    @property
    def intra(self) -> IntraTurn:
        return IntraTurn.from_json(self.intra_turn)

    @property
    def bandwidth_hz(self) -> float | None:
        """The FOG's output bandwidth: the entry's own, else its intra-turn part's."""
        return (number(self.doc, "bandwidth_hz") if "bandwidth_hz" in self.doc
                else self.intra.bandwidth_hz)

    @property
    def averaged(self) -> JsonValue:
        """Averages over angle: `intra_turn.averaged`, else an older result's name of it."""
        data = self.intra.averaged
        for key in AVERAGED_OLD_KEYS:
            data = data if data is not None else self.doc.get(key)
        return data

    def to_json(self) -> JsonObject:
        return dict(self.doc)

    @property
    def rate_error_U_rel(self) -> float | None:
        """The rate error's expanded uncertainty as result.json writes it
        (`rate_error_U_rel`; an older result's `rate_error_u_rel`)."""
        return (number(self.doc, "rate_error_U_rel") if "rate_error_U_rel" in self.doc
                else number(self.doc, "rate_error_u_rel"))

    @property
    def rate_instability_U_rel(self) -> float | None:
        """The instability's expanded uncertainty (`rate_instability_U_rel`; an older
        result's `rate_instability_u_rel`)."""
        return (number(self.doc, "rate_instability_U_rel") if "rate_instability_U_rel" in self.doc
                else number(self.doc, "rate_instability_u_rel"))

    @property
    def intra_turn_instability_U_rel(self) -> float | None:
        return _expanded(self.doc, "intra_turn_instability_U_rel",
                         "intra_turn_instability_u_rel")


@dataclass(frozen=True, slots=True)
class Half:
    """One half of a +/- pair (docs/method.md A3): the counter's and the FOG's mean rates."""

    counter_mean_dps: float | None
    counter_mean_ustd_dps: float | None
    fog_mean_dps: float | None
    fog_mean_ustd_dps: float | None
    t_centre_s: float | None
    turns: float | None
    sign: float | None

    @classmethod
    def from_json(cls, doc: JsonObject) -> Half:
        return cls(*(number(doc, k) for k in (
            "counter_mean_dps", "counter_mean_ustd_dps", "fog_mean_dps", "fog_mean_ustd_dps",
            "t_centre_s", "turns", "sign")))


@dataclass(frozen=True, slots=True)
class PairEntry:
    """One +/- pair's FOG cross-calibration (docs/method.md A3): `axes.<axis>.pairs[]`."""

    rate_dps: float
    k: float | None
    k_u: float | None
    w0_dps: float | None
    w0_u_dps: float | None
    drift_dps_per_h: float | None
    drift_u_dps_per_h: float | None
    method: str | None           # how k and w0 were found
    drift_source: str | None     # where the bias drift during the pair comes from
    budgets: tuple[JsonObject, ...]
    doc: JsonObject

    @property
    def half_sessions(self) -> tuple[int, ...]:
        """A resumed pair: the session each half came from (docs/resume.md)."""
        v = self.doc.get("half_sessions")
        return tuple(int(s) for s in v if isinstance(s, int | float)) \
            if isinstance(v, list) else ()

    @property
    def bias_model(self) -> str:
        return str(self.doc.get("bias_model", ""))

    @property
    def halves(self) -> tuple[Half, ...]:
        return tuple(Half.from_json(h) for h in objects(self.doc, "halves"))

    @property
    def w0_t_ref_s(self) -> float | None:
        """The time the bias w0 is referred to (a fit with a drift term)."""
        return number(self.doc, "w0_t_ref_s")

    @classmethod
    def from_json(cls, doc: JsonObject) -> PairEntry:
        rate = number(doc, "rate_dps")
        if rate is None:
            raise MalformedResult("pairs[]", "has no numeric rate_dps")
        return cls(rate_dps=rate, k=number(doc, "k"), k_u=number(doc, "k_u"),
                   w0_dps=number(doc, "w0_dps"), w0_u_dps=number(doc, "w0_u_dps"),
                   drift_dps_per_h=number(doc, "drift_dps_per_h"),
                   drift_u_dps_per_h=number(doc, "drift_u_dps_per_h"),
                   method=text(doc, "method"), drift_source=text(doc, "drift_source"),
                   budgets=objects(doc, "budgets"), doc=doc)

    def to_json(self) -> JsonObject:
        return dict(self.doc)

    @property
    def k_U(self) -> float | None:
        """k's expanded uncertainty as result.json writes it (`k_U`; an older result's
        `k_u`)."""
        return (number(self.doc, "k_U") if "k_U" in self.doc
                else number(self.doc, "k_u"))

    @property
    def w0_U_dps(self) -> float | None:
        """w0's expanded uncertainty (`w0_U_dps`; an older result's `w0_u_dps`)."""
        return (number(self.doc, "w0_U_dps") if "w0_U_dps" in self.doc
                else number(self.doc, "w0_u_dps"))


@dataclass(frozen=True, slots=True)
class NoiseFloor:
    """The FOG at rest (docs/method.md A5): its Allan deviation and bias."""

    source: str | None
    samples: int | None
    duration_s: float | None
    sample_std_dps: float | None
    mean_dps: float | None
    allan_tau_s: tuple[float, ...]
    allan_dev_dps: tuple[float, ...]
    doc: JsonObject

    @property
    def noise_dps(self) -> float | None:
        """The FOG's noise per sample, under any of the names results have used."""
        for key in ("noise_dps", "sigma_dps", "sample_std_dps"):
            if key in self.doc:
                return number(self.doc, key)
        return None

    @property
    def rate_hz(self) -> float | None:
        return number(self.doc, "rate_hz")

    @classmethod
    def from_json(cls, doc: JsonObject) -> NoiseFloor:
        def floats(key: str) -> tuple[float, ...]:
            v = doc.get(key)
            return tuple(x for x in v if isinstance(x, int | float)
                         and not isinstance(x, bool)) if isinstance(v, list) else ()
        return cls(source=text(doc, "source"), samples=integer(doc, "samples"),
                   duration_s=number(doc, "duration_s"),
                   sample_std_dps=number(doc, "sample_std_dps"),
                   mean_dps=number(doc, "mean_dps"), allan_tau_s=floats("allan_tau_s"),
                   allan_dev_dps=floats("allan_dev_dps"), doc=doc)

    def to_json(self) -> JsonObject:
        return dict(self.doc)


@dataclass(frozen=True, slots=True)
class LadderAxis:
    """One axis of the ladder: its rates, its pairs and its FOG's noise floor."""

    rates: tuple[RateEntry, ...]
    pairs: tuple[PairEntry, ...]
    noise_floor: NoiseFloor | None
    doc: JsonObject

    @classmethod
    def from_json(cls, doc: JsonObject) -> LadderAxis:
        floor = as_object(doc.get("noise_floor"))
        return cls(rates=tuple(RateEntry.from_json(r) for r in objects(doc, "rates")),
                   pairs=tuple(PairEntry.from_json(p) for p in objects(doc, "pairs")),
                   noise_floor=NoiseFloor.from_json(floor) if floor is not None else None,
                   doc=doc)

    def to_json(self) -> JsonObject:
        return dict(self.doc)


@dataclass(frozen=True, slots=True)
class LadderResult:
    """A rate-ladder run's result.json: the shared frame and the axes."""

    frame: ResultFrame
    axes: dict[str, LadderAxis]
    conditions_measured: JsonValue

    @classmethod
    def of(cls, doc: JsonObject) -> LadderResult:
        """The typed view of a conformed document."""
        return cls(frame=ResultFrame.of(doc),
                   axes={name: LadderAxis.from_json(a) for name, a in obj(doc, "axes").items()
                         if isinstance(a, dict)},
                   conditions_measured=doc.get("conditions_measured"))

    @classmethod
    def from_json(cls, doc: object) -> LadderResult:
        """The result, or MalformedResult naming the first malformed key path."""
        top = as_object(doc)
        if top is None:
            raise MalformedResult(layout.RESULT, "is not a JSON object")
        issues = Issues(strict=True)
        return cls.of(conform_frame(conform_ladder(top, issues), issues))

    @classmethod
    def conform(cls, doc: object) -> tuple[LadderResult, list[str]]:
        """The result with malformed containers dropped, and what was dropped (named)."""
        top = as_object(doc)
        if top is None:
            return cls.of({}), ["result.json (expected a mapping)"]
        issues = Issues(strict=False)
        return cls.of(conform_frame(conform_ladder(top, issues), issues)), issues.dropped

    def rates(self) -> list[tuple[str, RateEntry]]:
        """Every (axis, rate entry), in the result's order."""
        return [(name, r) for name, a in self.axes.items() for r in a.rates]

    def pairs(self) -> list[tuple[str, PairEntry]]:
        return [(name, p) for name, a in self.axes.items() for p in a.pairs]

    def to_json(self) -> JsonObject:
        return self.frame.to_json()


def add_budgets(doc: JsonObject,
                of_rate: Callable[[RateEntry, PairEntry | None, NoiseFloor | None],
                                  list[JsonValue]],
                of_pair: Callable[[PairEntry], list[JsonValue]]) -> JsonObject:
    """The analysis' result with a `budgets` list on every rate and pair, added in place
    (additions only): `of_rate` and `of_pair` lay them out from the typed entries; a rate
    is given the pair at its rate."""
    axes = doc.get("axes")
    for axis in axes.values() if isinstance(axes, dict) else ():
        if not isinstance(axis, dict):
            continue
        found = as_object(axis.get("noise_floor"))
        floor = NoiseFloor.from_json(found) if found is not None else None
        pairs = [p for p in _dicts(axis, "pairs") if number(p, "rate_dps") is not None]
        typed = [PairEntry.from_json(p) for p in pairs]
        for r in _dicts(axis, "rates"):
            if number(r, "set_rate_dps") is None:
                continue
            rate = RateEntry.from_json(r)
            pair = next((p for p in typed if p.rate_dps == abs(rate.set_rate_dps)), None)
            r["budgets"] = of_rate(rate, pair, floor)
        for p, entry in zip(pairs, typed, strict=True):
            p["budgets"] = of_pair(entry)
    return doc


def _dicts(doc: JsonObject, key: str) -> list[JsonObject]:
    """The entries of a list that are JSON objects (the same objects: budgets go into them)."""
    got = doc.get(key)
    return [v for v in got if isinstance(v, dict)] if isinstance(got, list) else []


def with_conditions_measured(doc: dict[str, object], fog_axes: Mapping[str, object]
                             ) -> dict[str, object]:
    """The analysis' result with what the bench measured itself (`conditions_measured`):
    the FOG's temperature per axis (procedures/rate_ladder/conditions.py), none when no
    half recorded it; the room: no sensor on this stand, not measured."""
    doc["conditions_measured"] = {
        "fog_temperature": {"source": "FOG frames' temperature field (table top, at the "
                                      "FOG), deg C, integer resolution", "axes": fog_axes}
        if fog_axes else None,
        "room": None,
    }
    return doc


# -- writing: the analysis's typed values as result.json spells them ---------------------------
#
# The analysis (bench/analysis, procedures/rate_ladder/analysis.py) computes typed values and
# never spells a key; the functions below lay them out as CONTRACT §3's `axes.<axis>.rates[]`,
# `pairs[]` and `noise_floor`, in the order result.json has always had them, and the readers
# above take them back. Non-finite numbers become null (JSON has no NaN).

def clean(x: object) -> JsonValue:
    """Non-finite floats replaced by None, recursively; tuples as lists."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, Mapping):
        return {str(k): clean(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [clean(v) for v in x]
    if x is None or isinstance(x, str | int):
        return x
    raise TypeError(f"result.json cannot hold a {type(x).__name__}: {x!r}")


def counter_budget_json(b: CounterBudget) -> JsonObject:
    """The counter chain's timing terms (docs/method.md A1, D1); an applied time-base
    correction's e and u(e) only when one was applied (issue 58: without one, the bytes as
    before)."""
    out: JsonObject = {"timestamp_u_s": b.timestamp_u_s, "trigger_jitter_s": b.trigger_jitter_s,
                       "timebase_limit_rel": b.timebase_limit_rel, "edge_u_s": b.edge_u_s,
                       "time_tie_u_s": b.time_tie_u_s,
                       "period_u_s": b.period_u_s, "timebase_u_rel": b.timebase_u_rel}
    if b.timebase_correction_u_rel > 0.0 or b.timebase_correction_rel != 0.0:
        out["timebase_correction_rel"] = b.timebase_correction_rel
        out["timebase_correction_u_rel"] = b.timebase_correction_u_rel
    return out


def turns_json(tr: TurnsResult) -> JsonObject:
    """Eq. 1-2 of one direction: the per-turn rates, the rate error and its budget, the
    rate instability and its timing floor (docs/method.md A1-A2)."""
    return {
        "set_rate_dps": tr.set_rate_dps,
        "turns": tr.turns,
        "counter_rate_dps": list(tr.counter_rate_dps),
        "mean_rate_dps": tr.mean_rate_dps,
        "rate_error_rel": tr.rate_error_rel,
        "rate_error_u_rel": tr.rate_error_u_rel,
        "rate_instability_rel": tr.rate_instability_rel,
        "rate_instability_floor_rel": tr.rate_instability_floor_rel,
        "rate_error_budget": {"timing_u_rel": tr.timing_u_rel,
                              "timebase_u_rel": tr.timebase_u_rel,
                              "repeatability_u_rel": tr.repeatability_u_rel,
                              "repeatability_basis": tr.repeatability_basis,
                              "repeatability_dof": tr.repeatability_dof,
                              "dof_eff": tr.dof_eff,
                              "coverage_factor": tr.coverage_factor,
                              **counter_budget_json(tr.budget)},
    }


def harmonic_json(h: HarmonicResult) -> JsonObject:
    return {"order": h.order, "amplitude_rel": h.amplitude_rel,
            "amplitude_u_rel": h.amplitude_u_rel, "phase_deg": h.phase_deg,
            "phase_u_deg": h.phase_u_deg, "detected": h.detected,
            "amplitude_upper_rel": h.amplitude_upper_rel, "interval_factor": h.interval_factor}


def mains_json(m: MainsResult) -> JsonObject:
    return {"frequency_hz": m.frequency_hz, "amplitude_dps": m.amplitude_dps,
            "amplitude_u_dps": m.amplitude_u_dps, "phase_deg": m.phase_deg,
            "phase_u_deg": m.phase_u_deg, "detected": m.detected,
            "significance_chi2": m.significance, "source": m.source,
            "amplitude_upper_dps": m.amplitude_upper_dps, "interval_factor": m.interval_factor}


def binned_json(b: BinnedSystematic) -> JsonObject:
    return {"bin_deg": b.bin_deg, "centres_deg": list(b.centres_deg),
            "deviation_rel": list(b.deviation_rel), "u_rel": list(b.u_rel),
            "peak_to_peak_rel": b.peak_to_peak_rel}


def inflation_json(n: NoiseInflation) -> JsonObject:
    return {"block_deg": n.block_deg, "blocks": n.blocks, "ratio": n.ratio,
            "applied": n.factor}


def systematic_json(s: SystematicResult) -> JsonObject:
    """The systematic intra-turn rate (docs/method.md A4)."""
    return {"harmonics": [harmonic_json(h) for h in s.harmonics],
            "mains": mains_json(s.mains) if s.mains else None,
            "binned": binned_json(s.binned),
            "residual_std_dps": s.residual_std_dps,
            "noise_inflation": inflation_json(s.inflation),
            "detection": dict(s.detection)}


def averaged_json(a: AveragedInstability) -> JsonObject:
    """The random part averaged over an angle (docs/method.md A5)."""
    from bench.analysis.random_part import LEVEL

    return {"angle_deg": a.angle_deg, "instability_rel": a.instability_rel,
            "u_rel": a.u_rel,
            "floor_rel": a.floor_rel, "corrected_rel": a.corrected_rel,
            "corrected_upper_rel": a.corrected_upper_rel,
            "corrected_lower_rel": a.corrected_lower_rel, "resolved": a.resolved,
            "corrected_ustd_rel": a.corrected_ustd_rel, "ustd_rel": a.ustd_rel,
            "measured_resolved": a.measured_resolved,
            "measured_upper_rel": a.measured_upper_rel,
            "interval_level": LEVEL, "dof": a.dof,
            "blocks": a.blocks, "samples_per_block": a.samples_per_block}


def random_json(r: RandomPartResult) -> JsonObject:
    """The random intra-turn rate and its floor-corrected interval (docs/method.md A5)."""
    from bench.analysis.random_part import LEVEL, MC_DRAWS

    return {"instability_rel": r.instability_rel, "floor_rel": r.floor_rel,
            "floor_source": r.floor_source, "corrected_rel": r.corrected_rel,
            "corrected_upper_rel": r.corrected_upper_rel,
            "corrected_lower_rel": r.corrected_lower_rel,
            "corrected_u_rel": r.corrected_u_rel, "interval_level": LEVEL,
            "interval_method": "JCGM 101 Monte Carlo of raw^2 - floor^2 (scaled "
                               "inverse chi-square per variance)",
            "floor_dof": r.floor_dof, "resolved": r.resolved,
            "raw_resolved": r.raw_resolved, "raw_upper_rel": r.raw_upper_rel,
            "raw_ustd_rel": r.raw_ustd_rel, "raw_dof": r.raw_dof, "mc_draws": MC_DRAWS,
            "corrected_ustd_rel": r.corrected_ustd_rel,
            "bandwidth_hz": r.bandwidth_hz, "std_dps": r.std_dps,
            "samples": r.samples, "averaged": [averaged_json(a) for a in r.averaged]}


def rate_json(r: RateResult) -> JsonObject:
    """One commanded rate and direction (docs/method.md A1-A5): `axes.<axis>.rates[]`
    without what the ladder adds after judging it (`with_sigma_terms`, `with_outcome`)."""
    d = turns_json(r.turns_result)
    d["intra_turn_instability_rel"] = r.random.instability_rel
    d["intra_turn_instability_corrected_rel"] = r.random.corrected_rel
    # docs/method.md A5: U of a std from the record's samples (white random part assumed)
    d["intra_turn_instability_u_rel"] = r.random.raw_U_rel
    # docs/method.md A5: the corrected figure's U only when it is resolved (JCGM 101);
    # otherwise it is stated as '< intra_turn.corrected_upper_rel'
    d["intra_turn_instability_corrected_u_rel"] = r.random.corrected_u_rel
    d["systematic"] = systematic_json(r.systematic)
    d["intra_turn"] = random_json(r.random)
    d["windows"] = [dict(w) for w in r.windows]
    if r.verdict is not None:
        d["verdict"] = r.verdict
        d["judgement"] = clean(r.judgement)
    return as_object(clean(d)) or {}


def with_sigma_terms(d: JsonObject, u_rel: float, upper_rel: float, lower_rel: float,
                     resolved: bool, ustd_rel: float | None = None) -> JsonObject:
    """A rate's entry with eq. 2's U, its chi-square limits, whether it is resolved above
    the timing floor and its standard uncertainty (docs/method.md A1-A2), added in place."""
    d["rate_instability_u_rel"] = u_rel
    d["rate_instability_ustd_rel"] = ustd_rel
    d["rate_instability_upper_rel"] = upper_rel
    d["rate_instability_lower_rel"] = lower_rel
    d["rate_instability_resolved"] = resolved
    return d


def with_outcome(d: JsonObject, *, session: int, fog_lost_frames: int,
                 checks: list[JsonObject], verdict: str) -> JsonObject:
    """A rate's entry with the session that measured it, the FOG frames its halves lost,
    its conformity checks and verdict, added in place."""
    d["session"] = session
    d["fog_lost_frames"] = fog_lost_frames
    d["checks"] = list[JsonValue](checks)
    d["verdict"] = verdict
    return d


def half_json(h: HalfMean) -> JsonObject:
    return {"sign": h.sign, "turns": h.turns, "t_centre_s": h.t_centre_s,
            "fog_mean_dps": h.fog_mean_dps, "fog_mean_u_dps": h.fog_mean_u_dps,
            "counter_mean_dps": h.counter_mean_dps,
            "counter_mean_u_dps": h.counter_mean_u_dps}


def crosscal_json(c: CrossCalibration) -> JsonObject:
    """k, w0 (at t_ref) and the bias drift with U (docs/method.md A3, eq. 5-6)."""
    return {
        "k": c.k, "k_u": c.k_u, "w0_dps": c.w0_dps, "w0_u_dps": c.w0_u_dps,
        "w0_t_ref_s": c.t_ref_s,
        "drift_dps_per_h": c.drift_dps_per_s * SECONDS_PER_HOUR,
        "drift_u_dps_per_h": c.drift_u_dps_per_s * SECONDS_PER_HOUR,
        "method": c.method, "drift_source": c.drift_source, "k_eq5": c.k_eq5,
        "chi2": c.chi2, "dof": c.dof, "birge_ratio": c.birge_ratio,
        "halves": [half_json(h) for h in c.halves],
    }


def pair_json(p: PairResult) -> JsonObject:
    """One +/- pair's FOG cross-calibration (docs/method.md A3): `axes.<axis>.pairs[]`."""
    d = {"rate_dps": p.rate_dps, **crosscal_json(p.cal),
         "noise_inflation": inflation_json(p.noise_inflation),
         "half_sessions": list(p.sessions), "bias_model": p.bias_model}
    return as_object(clean(d)) or {}


def noise_floor_json(samples: int, duration_s: float, sample_std_dps: float,
                     mean_dps: float, curve: AllanCurve) -> JsonObject:
    """The FOG at rest (docs/method.md A5): `axes.<axis>.noise_floor`."""
    return {"source": "Allan deviation of a static FOG record",
            "samples": samples, "duration_s": duration_s,
            "sample_std_dps": sample_std_dps,
            "mean_dps": mean_dps,   # bias at rest (bench control)
            "allan_tau_s": list(curve.tau_s), "allan_dev_dps": list(curve.adev)}


def axis_json(rates: list[JsonObject], pairs: list[JsonObject],
              noise_floor: JsonObject | None) -> JsonObject:
    return {"rates": list[JsonValue](rates), "pairs": list[JsonValue](pairs),
            "noise_floor": noise_floor}
