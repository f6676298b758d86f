"""The frame every kind's result.json shares: its run header, checks and verdict, typed.

result.json is read back by the certificate, the DCC, the records and the station. A
malformed part must not crash them (the operator would be left with raw data and no
report), nor be read as if it were sound: the strict reader (`from_json`) refuses it
naming the key path; the lenient one (`conform`) drops the malformed container, names it
(the certificate's section Deviations lists it) and keeps the rest. Both walk the same
typed parsers below, which a kind's result module (procedures/<kind>/result.py) uses for
its own part, so one module per kind spells its keys and this one spells the frame's.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TypeVar

from bench.analysis.finite import finite_number
from bench.core import rundir_layout as layout
from bench.report.corrections import Correction
from drivers.json_types import JsonObject, JsonValue

#: a key path inside result.json: `axes.outer.rates[0]`
KeyPath = tuple[str | int, ...]

T = TypeVar("T")


class MalformedResult(ValueError):
    """A part of result.json that is not what its reader needs; `path` names it."""

    def __init__(self, path: str, problem: str) -> None:
        super().__init__(f"result.json: {path} {problem}")
        self.path = path
        self.problem = problem


def where(path: KeyPath) -> str:
    """`('axes', 'outer', 'rates', 0)` -> `axes.outer.rates[0]`."""
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out


class Issues:
    """What a reader found malformed: raised at once (strict) or collected (lenient)."""

    def __init__(self, *, strict: bool) -> None:
        self.strict = strict
        self.dropped: list[str] = []

    def report(self, path: KeyPath, problem: str) -> None:
        if self.strict:
            raise MalformedResult(where(path) or layout.RESULT, problem)
        self.dropped.append(f"{where(path)} ({problem})")


def is_number(x: object) -> bool:
    """A finite number, or text that reads as one (as a hand-edited result may hold)."""
    if isinstance(x, bool) or not isinstance(x, int | float | str):
        return False
    try:
        return math.isfinite(float(x))
    except ValueError:
        return False


def as_object(value: object) -> JsonObject | None:
    """`value` as a JSON object (a copy), or None when it is not one."""
    if not isinstance(value, Mapping):
        return None
    return {str(k): v for k, v in value.items()}


def _found(value: object) -> str:
    return type(value).__name__


def _present(doc: JsonObject, key: str, path: KeyPath, issues: Issues,
             expected: type[dict[str, JsonValue]] | type[list[JsonValue]]) -> JsonValue:
    """`doc[key]` when it is there and of the `expected` container type; else None (null
    means absent and goes, kept as read by a strict reader; another type is dropped and
    named)."""
    value = doc.get(key)
    if value is None:
        if key in doc and not issues.strict:
            del doc[key]
        return None
    if not isinstance(value, Mapping if expected is dict else list):
        shape = "a mapping" if expected is dict else "a list"
        issues.report((*path, key), f"expected {shape}, found {_found(value)}")
        del doc[key]
        return None
    return value


def conform_object(doc: JsonObject, key: str, path: KeyPath, issues: Issues,
                   inner: Callable[[JsonObject, KeyPath, Issues], JsonObject] | None = None
                   ) -> None:
    """`doc[key]` kept when it is a mapping (then conformed by `inner`)."""
    found = as_object(_present(doc, key, path, issues, dict))
    if found is not None:
        doc[key] = inner(found, (*path, key), issues) if inner is not None else found


def conform_list(doc: JsonObject, key: str, path: KeyPath, issues: Issues,
                 item: Callable[[JsonObject, KeyPath, Issues], JsonObject] | None = None,
                 numeric: str | None = None) -> None:
    """`doc[key]` kept when it is a list of mappings (each conformed by `item`); an entry
    that is no mapping, or lacks the number `numeric` it means nothing without, is
    dropped and named."""
    value = _present(doc, key, path, issues, list)
    if not isinstance(value, list):
        return
    kept: list[JsonValue] = []
    for i, entry in enumerate(value):
        obj = as_object(entry)
        if obj is None:
            issues.report((*path, key, i), f"expected a mapping, found {_found(entry)}")
            continue
        if item is not None:
            obj = item(obj, (*path, key, i), issues)
        if numeric is not None and not is_number(obj.get(numeric)):
            issues.report((*path, key, i), f"no numeric {numeric}")
            continue
        kept.append(obj)
    doc[key] = kept


def conform_plain_list(doc: JsonObject, key: str, path: KeyPath, issues: Issues) -> None:
    """`doc[key]` kept when it is a list (its entries unchecked)."""
    _present(doc, key, path, issues, list)


def conform_each(doc: JsonObject, path: KeyPath, issues: Issues,
                 inner: Callable[[JsonObject, KeyPath, Issues], JsonObject] | None = None
                 ) -> JsonObject:
    """Every value of `doc` a mapping (conformed by `inner`); the others dropped."""
    for key in list(doc):
        conform_object(doc, key, path, issues, inner)
    return doc


# -- typed leaves ----------------------------------------------------------------------------

def text(doc: Mapping[str, JsonValue], key: str) -> str | None:
    value = doc.get(key)
    return value if isinstance(value, str) else None


def number(doc: Mapping[str, JsonValue], key: str) -> float | None:
    """A finite number as result.json holds it (an int stays an int), else None."""
    value = doc.get(key)
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return value if math.isfinite(value) else None


def integer(doc: Mapping[str, JsonValue], key: str) -> int | None:
    value = doc.get(key)
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def flag(doc: Mapping[str, JsonValue], key: str) -> bool | None:
    value = doc.get(key)
    return value if isinstance(value, bool) else None


def obj(doc: Mapping[str, JsonValue], key: str) -> JsonObject:
    """A mapping entry ({} when absent: conform dropped what was no mapping)."""
    return as_object(doc.get(key)) or {}


def objects(doc: Mapping[str, JsonValue], key: str) -> tuple[JsonObject, ...]:
    value = doc.get(key)
    if not isinstance(value, list):
        return ()
    return tuple(o for o in (as_object(v) for v in value) if o is not None)


# -- the frame ---------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class Check:
    """One conformity check (bench.report.conformity): what was judged and the verdict."""

    axis: str | None
    quantity: str | None
    verdict: str | None
    set_rate_dps: float | None
    rule: str | None
    tolerance: float | None  # in the unit its key names (tolerance_rel, tolerance_dph...)
    doc: JsonObject          # every key, in result.json's order
    one_sided: bool          # an unresolved value, judged on its upper limit
    upper_rel: float | None  # the 97.5 % limit (or the interval's upper end)
    lower_rel: float | None  # the interval's lower end of an asymmetric value
    capability_ratio: float | None  # U/T (RMG 63-2003)
    capability_ok: bool | None
    reason: str | None       # why the verdict is not a pass

    @classmethod
    def from_json(cls, doc: JsonObject) -> Check:
        tolerance = next((number(doc, k) for k in ("tolerance_rel", "tolerance_dph",
                                                     *sorted(k for k in doc
                                                             if k.startswith("tolerance")))
                          if k in doc), None)
        return cls(text(doc, "axis"), text(doc, "quantity"), text(doc, "verdict"),
                   number(doc, "set_rate_dps"), text(doc, "rule"), tolerance, doc,
                   one_sided=bool(doc.get("one_sided")), upper_rel=number(doc, "upper_rel"),
                   lower_rel=number(doc, "lower_rel"),
                   capability_ratio=number(doc, "capability_ratio"),
                   capability_ok=flag(doc, "capability_ok"), reason=text(doc, "reason"))

    @property
    def tolerance_rel(self) -> float | None:
        """The tolerance of a relative quantity (None for one in °/h, °/s...)."""
        return number(self.doc, "tolerance_rel")

    @property
    def floor_name(self) -> str | None:
        """What an unresolved value was not resolved above ('timing floor', 'FOG floor':
        docs/method.md D2), as the kind names it."""
        return text(self.doc, "floor_name")

    def figure(self, key: str) -> float | None:
        """A figure the check states under a unit-suffixed key (`U_rel`, `tolerance_dph`,
        `upper_rel`...: which ones depends on the quantity's unit), read as the DCC always
        read them (numeric text too); None when absent or no finite number."""
        return finite_number(self.doc.get(key))

    def states(self, key: str) -> bool:
        """Whether the check states `key` at all (the quantity's unit is named by which
        `value_<unit>` it holds)."""
        return key in self.doc

    def to_json(self) -> JsonObject:
        return dict(self.doc)


@dataclass(frozen=True, slots=True)
class MeasuredHalf:
    """The FOG's temperature over one half, from its frames (`conditions_measured.
    fog_temperature.axes.<axis>.halves[]`, procedures that record it)."""

    half: float | None
    set_rate_dps: float | None
    min_c: float | None
    mean_c: float | None
    max_c: float | None

    @classmethod
    def from_json(cls, doc: JsonObject) -> MeasuredHalf:
        return cls(*(number(doc, k) for k in ("half", "set_rate_dps", "min_c", "mean_c",
                                               "max_c")))


def fog_temperature(doc: Mapping[str, JsonValue]
                    ) -> dict[str, tuple[MeasuredHalf, ...]] | None:
    """Per axis, the halves' FOG temperatures the run measured; None when it measured none."""
    fog = obj(obj(doc, "conditions_measured"), "fog_temperature")
    axes = as_object(fog.get("axes"))
    if axes is None:
        return None
    return {axis: tuple(MeasuredHalf.from_json(h) for h in objects(found, "halves"))
            for axis, ax in axes.items() if (found := as_object(ax)) is not None}


@dataclass(frozen=True, slots=True)
class FogAxisTemperature:
    """The FOG's temperature over all of one axis's halves, from its frames
    (`conditions_measured.fog_temperature.axes.<axis>`; per half: `fog_temperature`)."""

    min_c: float | None
    mean_c: float | None
    max_c: float | None

    @classmethod
    def from_json(cls, doc: JsonObject) -> FogAxisTemperature:
        # finite_number's reading (numeric text too), as the certificate always read them
        return cls(*(finite_number(doc.get(k)) for k in ("min_c", "mean_c", "max_c")))


@dataclass(frozen=True, slots=True)
class MeasuredConditions:
    """What the bench measured of the conditions itself (`conditions_measured`): the room
    where a sensor said so, the FOG's temperature per axis; empty when it measured none."""

    room: JsonObject
    fog_axes: dict[str, FogAxisTemperature]

    @classmethod
    def from_json(cls, doc: JsonObject) -> MeasuredConditions:
        axes = obj(obj(doc, "fog_temperature"), "axes")
        return cls(room=obj(doc, "room"),
                   fog_axes={str(axis): FogAxisTemperature.from_json(found)
                             for axis, ax in axes.items()
                             if (found := as_object(ax)) is not None})


@dataclass(frozen=True, slots=True)
class Specification:
    """Where the procedure's tolerances come from (`specification`: a datasheet, a
    standard) and what its quantities mean there; a certificate without one says so."""

    source: JsonValue        # as written (text_of prints it); falsy: not identified
    definitions: JsonObject  # quantity key -> its definition in the source

    @classmethod
    def of(cls, value: object) -> Specification | None:
        """A result's (or a procedure file's) specification; None when it states none."""
        doc = as_object(value)
        if not doc:
            return None
        return cls(source=doc.get("source"), definitions=obj(doc, "definitions"))


@dataclass(frozen=True, slots=True)
class HashedFile:
    """A file and its SHA-256 as the run recorded it (`raw_files[]`): printed as written,
    its byte count read as the certificate always read it (numeric text too)."""

    path: JsonValue
    sha256: JsonValue
    size_bytes: float | None

    @classmethod
    def from_json(cls, doc: JsonObject) -> HashedFile:
        return cls(doc.get("path"), doc.get("sha256"), finite_number(doc.get("bytes")))


@dataclass(frozen=True, slots=True)
class CertificateSettings:
    """The certificate settings (`certificate`: the lab file's under the run's): who
    issues it and for whom; each printed as written (an absent one says so)."""

    laboratory: JsonValue = None
    address: JsonValue = None
    accreditation: JsonValue = None
    customer: JsonValue = None
    customer_address: JsonValue = None
    customer_contact: JsonValue = None
    site: JsonValue = None
    entries: tuple[tuple[str, JsonValue], ...] = ()   # every setting, in the file's order

    @classmethod
    def of(cls, value: JsonValue, issuer: tuple[tuple[str, str], ...] = ()
           ) -> CertificateSettings:
        """The settings `value` holds (none when it is no mapping), with the register's
        `issuer` identity (laboratory, address, code, accreditation) in place of theirs
        when it is given (issue 54: nothing of the files' for them then)."""
        doc = dict(value) if isinstance(value, dict) else {}
        if issuer:
            for key in ("laboratory", "address", "code", "accreditation"):
                doc.pop(key, None)
            doc.update(dict(issuer))
        return cls(laboratory=doc.get("laboratory"), address=doc.get("address"),
                   accreditation=doc.get("accreditation"), customer=doc.get("customer"),
                   customer_address=doc.get("customer_address"),
                   customer_contact=doc.get("customer_contact"), site=doc.get("site"),
                   entries=tuple(doc.items()))


@dataclass(frozen=True, slots=True)
class ToleranceBand:
    """A relative tolerance for set rates below `below_dps` (None: every rate above the
    previous band's)."""

    below_dps: float | None
    rel: float | None


@dataclass(frozen=True, slots=True)
class Tolerance:
    """One quantity's tolerance as the procedure states it (`method.tolerance`): one
    number (its unit in the key: `<quantity>_dph: 0.5`) or rate bands, in order."""

    quantity: str
    value: float | None
    bands: tuple[ToleranceBand, ...]

    @classmethod
    def all_of(cls, value: JsonValue) -> tuple[Tolerance, ...]:
        """Every quantity's tolerance in a `tolerance` mapping (none when it is none); a
        band that is no mapping is left out. Numbers read as finite_number reads them."""
        doc = value if isinstance(value, dict) else {}
        return tuple(cls(str(quantity), finite_number(bands), tuple(
            ToleranceBand(finite_number(b.get("below_dps")), finite_number(b.get("rel")))
            for b in (bands if isinstance(bands, list) else []) if isinstance(b, dict)))
            for quantity, bands in doc.items())


def _stated_text(x: object) -> str | None:
    return str(x) if x is not None and str(x).strip() else None


def _stated_number(x: object) -> float | None:
    return float(x) if isinstance(x, int | float) and not isinstance(x, bool) \
        and math.isfinite(float(x)) else None


def correction_of(d: Mapping[str, object]) -> Correction:
    """One correction as a corrections file or result.json's `corrections[]` states it
    (or `bench impact` finds due: the same keys)."""
    return Correction(str(d.get("where") or "?"), _stated_text(d.get("serial")),
                      _stated_text(d.get("model")), str(d.get("quantity") or "?"),
                      _stated_number(d.get("value")), _stated_number(d.get("U")),
                      _stated_text(d.get("source")), _stated_text(d.get("reason")))


def corrections_of(doc: object) -> tuple[Correction, ...]:
    """The corrections a result states it applied (none for a run analysed as measured)."""
    stated = doc.get("corrections") if isinstance(doc, Mapping) else None
    return tuple(correction_of(d) for d in (stated if isinstance(stated, list) else [])
                 if isinstance(d, Mapping))


@dataclass(frozen=True, slots=True)
class RunDates:
    """When the run was created, first started and last ended (`dates`), as written."""

    created_utc: str | None
    started_utc: str | None
    completed_utc: str | None

    @classmethod
    def from_json(cls, doc: JsonObject) -> RunDates:
        return cls(*(text(doc, k) for k in ("created_utc", "started_utc", "completed_utc")))


@dataclass(frozen=True, slots=True)
class RunSession:
    """One session of the run and how it ended (`run_sessions[]`, bench.core.journal's
    SessionEnding): a resume is a session of the same run."""

    session: int | None
    started_utc: str | None
    ended_utc: str | None
    ended: str | None       # completed, aborted, refused, killed or crashed; None: running
    performer: str | None
    os_user: str | None

    @classmethod
    def from_json(cls, doc: JsonObject) -> RunSession:
        return cls(integer(doc, "session"), text(doc, "started_utc"), text(doc, "ended_utc"),
                   text(doc, "ended"), text(doc, "performer"), text(doc, "os_user"))


def conform_frame(doc: JsonObject, issues: Issues) -> JsonObject:
    """The frame's containers checked, in place (the kind's part is its result module's)."""
    conform_object(doc, "stand", (), issues)
    conform_object(doc, "instruments", (), issues, conform_each)
    for key in ("dates", "conditions", "certificate", "method", "procedure_file"):
        conform_object(doc, key, (), issues)
    conform_list(doc, "raw_files", (), issues)
    conform_list(doc, "checks", (), issues)
    return doc


@dataclass(frozen=True, slots=True)
class ResultFrame:
    """What every kind's result.json says about the run (bench.report.codec.ResultHead):
    the header, the decision rule, the method, the checks and the verdict. Every part is
    optional: a hand-made or older result may lack it, and the certificate says so."""

    schema: str | None
    procedure: str | None
    verdict: str | None
    title: str | None
    run_dir: str | None
    procedure_file: JsonObject   # result.json's: the procedure file's name and SHA-256
    stand: JsonObject
    instruments: dict[str, JsonObject]
    dates: RunDates
    conditions: JsonObject | None
    conditions_measured: MeasuredConditions
    specification: Specification | None
    certificate: JsonObject      # the certificate settings (the lab file's under the run's)
    sessions: int | None
    run_sessions: tuple[RunSession, ...]
    aborted: bool
    ended: str | None        # how the last session ended (None: no word yet)
    deviations: tuple[JsonValue, ...]  # a result's own deviations (hand-made or older ones)
    raw_files: tuple[JsonObject, ...]
    decision_rule: str | None
    method: JsonObject
    checks: tuple[Check, ...]
    records: JsonObject      # what the run says for the records (calibration state)
    corrections: tuple[Correction, ...]   # the instrument corrections it applied (issue 58)
    doc: JsonObject          # the whole document as read, in result.json's order

    @classmethod
    def conform(cls, doc: object) -> tuple[ResultFrame, list[str]]:
        """The frame with malformed containers dropped, and the list of what was dropped."""
        issues = Issues(strict=False)
        top = as_object(doc)
        if top is None:
            return cls.of({}), ["result.json (expected a mapping)"]
        return cls.of(conform_frame(top, issues)), issues.dropped

    @classmethod
    def from_json(cls, doc: object) -> ResultFrame:
        """The frame, or MalformedResult naming the first malformed key path."""
        top = as_object(doc)
        if top is None:
            raise MalformedResult(layout.RESULT, "is not a JSON object")
        return cls.of(conform_frame(top, Issues(strict=True)))

    @classmethod
    def of(cls, doc: JsonObject) -> ResultFrame:
        """The frame of a conformed document."""
        return cls(
            schema=text(doc, "schema"), procedure=text(doc, "procedure"),
            verdict=text(doc, "verdict"), title=text(doc, "title"),
            run_dir=text(doc, "run_dir"), procedure_file=obj(doc, "procedure_file"),
            stand=obj(doc, "stand"),
            instruments={k: v for k, v in obj(doc, "instruments").items()
                         if isinstance(v, dict)},
            dates=RunDates.from_json(obj(doc, "dates")),
            conditions=as_object(doc.get("conditions")),
            conditions_measured=MeasuredConditions.from_json(obj(doc, "conditions_measured")),
            specification=Specification.of(doc.get("specification")), certificate=obj(doc, "certificate"),
            sessions=integer(doc, "sessions"),
            run_sessions=tuple(RunSession.from_json(x) for x in objects(doc, "run_sessions")),
            aborted=bool(doc.get("aborted")), ended=text(doc, "ended"),
            deviations=tuple(found) if isinstance(found := doc.get("deviations"), list) else (),
            raw_files=objects(doc, "raw_files"), decision_rule=text(doc, "decision_rule"),
            method=obj(doc, "method"),
            checks=tuple(Check.from_json(c) for c in objects(doc, "checks")),
            records=obj(doc, "records"), corrections=corrections_of(doc), doc=doc)

    @property
    def hashed_raw_files(self) -> tuple[HashedFile, ...]:
        """The raw files the run recorded, each with its digest."""
        return tuple(HashedFile.from_json(f) for f in self.raw_files)

    @property
    def simulated(self) -> bool:
        """Whether the stand ran as its simulated twins."""
        return bool(self.stand.get("simulated"))

    def get(self, key: str) -> JsonValue:
        """A top-level entry the frame does not type (a kind's part, a later addition)."""
        return self.doc.get(key)

    def part(self, key: str) -> JsonObject:
        """A kind's own top-level part as a mapping, {} when the result has none (or has
        no mapping there): what a kind without a typed result module reads its keys from."""
        return obj(self.doc, key)

    def to_json(self) -> JsonObject:
        return dict(self.doc)


def parse_each(items: tuple[JsonObject, ...], parse: Callable[[JsonObject], T]) -> tuple[T, ...]:
    return tuple(parse(i) for i in items)
