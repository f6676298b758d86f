"""The rate ladder's result.json, typed: the one module that spells its keys (CONTRACT §3).

`LadderResult.from_json` reads a result.json (refusing a malformed one, naming the key
path), `LadderResult.conform` reads it leniently for the certificate (a malformed
container dropped and named, the rest kept), `to_json` gives the document back byte for
byte as `bench analyze` writes it (keys in their order, numbers as they were). Readers
(certificate, DCC, records, station, summary) take attributes from here.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TypedDict

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

__all__ = ["Half", "Harmonic", "IntraTurn", "LadderAxis", "Mains", "LadderResult", "MalformedResult", "NoiseFloor", "PairEntry",
           "RateEntry", "add_budgets", "with_conditions_measured"]


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
