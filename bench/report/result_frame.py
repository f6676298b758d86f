"""The frame every kind's result.json shares: its run header, checks and verdict, typed
(`ResultFrame`, a msgspec Struct: its fields are the keys, msgspec reads them).

result.json is read back by the certificate, the DCC, the records and the station. A
malformed part must not crash them (the operator would be left with raw data and no
report), nor be read as if it were sound: the strict reader (`from_json`) refuses it
naming the key path; the lenient one (`conform`) drops the malformed container, names it
(the certificate's section Deviations lists it) and keeps the rest. Both are one loop
(`decode`): msgspec decodes, and a value it refuses is taken out and decoding tried again,
so a field's default reads "not stated". A run's analysis gives its frame typed
(`ResultFrame.analysed`: its ResultHead's attributes, no JSON in between).
A kind's codec reads its own part with the same loop (procedures/rate_ladder/codec.py).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeAlias, TypeVar, cast

import msgspec
from msgspec import UNSET

from bench.analysis.finite import finite_number
from bench.core import rundir_layout as layout
from bench.report.corrections import Correction
from drivers.json_types import JsonLike, JsonObject, JsonValue

if TYPE_CHECKING:
    Json: TypeAlias = JsonValue
    #: the kind's body as its analysis gave it (bench/report/codec.py ResultPart)
    Body: TypeAlias = msgspec.Struct | Mapping[str, JsonLike] | None
else:  # msgspec takes no recursive alias: a JSON value as written, unchecked
    Json = Body = Any

#: a key path inside result.json: `axes.outer.rates[0]`
KeyPath = tuple[str | int, ...]

S = TypeVar("S", bound=msgspec.Struct)


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


def as_object(value: object) -> JsonObject | None:
    """`value` as a JSON object (a copy), or None when it is not one."""
    if not isinstance(value, Mapping):
        return None
    return {str(k): v for k, v in value.items()}


# -- leaves of a mapping a reader reads as written --------------------------------------------

def text(doc: Mapping[str, JsonValue], key: str) -> str | None:
    value = doc.get(key)
    return value if isinstance(value, str) else None


def obj(doc: Mapping[str, JsonValue], key: str) -> JsonObject:
    """A mapping entry ({} when absent: conform dropped what was no mapping)."""
    return as_object(doc.get(key)) or {}


# -- msgspec's refusals in result.json's words, and the one reading loop ----------------------

_AT = re.compile(r" - at `\$(?P<path>[^`]*)`$")
_MISSING = re.compile(r"^Object missing required field `(?P<key>[^`]+)`")
_EXPECTED = re.compile(r"^Expected `(?P<want>[^`]+)`, got `(?P<got>[^`]+)`")
_STEP = re.compile(r"\.(?P<key>[^.\[]+)|\[(?P<index>\d+|\.\.\.)\]")
#: msgspec's type names, as a reader of result.json says them
_TYPES = {"float": "a number", "int": "an integer", "bool": "true or false",
          "object": "an object", "array": "a list", "str": "text", "null": "null"}


def problem_of(err: msgspec.ValidationError) -> tuple[str, str]:
    """msgspec's refusal in result.json's words: (msgspec's key path below the node it
    decoded, `.axes[...].turns` or '' at the node itself; the problem), a missing key
    named at its own path (`.rates[0].set_rate_dps`, 'missing'). The kinds' codecs put
    their part's root (and a mapping's key, which msgspec does not name) before it."""
    text = str(err)
    at = _AT.search(text)
    path = at["path"] if at else ""
    text = text[:at.start()] if at else text
    if m := _MISSING.match(text):
        return f"{path}.{m['key']}", "missing"
    if m := _EXPECTED.match(text):
        want = " or ".join(_TYPES.get(t, t) for t in m["want"].split(" | "))
        return path, f"expected {want}, got {m['got']}"
    return path, text


#: JSON's types as msgspec names them in a refusal (the others by their Python name)
_JSON_TYPES = {dict: "object", list: "array", type(None): "null"}


def _at(node: JsonValue, steps: list[str | int], got: str
        ) -> Iterator[tuple[KeyPath, JsonValue]]:
    """(key path, value) of each place `steps` names in `node` (msgspec's `[...]`: a
    mapping's key it does not name, tried key by key) whose value is of type `got` ('':
    any)."""
    if not steps:
        if not got or _JSON_TYPES.get(type(node), type(node).__name__) == got:
            yield (), node
        return
    step, rest = steps[0], steps[1:]
    for k in list(node) if step == "..." and isinstance(node, dict) else [step]:
        if isinstance(node, dict) and isinstance(k, str) and k in node:
            yield from (((k, *p), v) for p, v in _at(node[k], rest, got))
        elif isinstance(node, list) and isinstance(k, int) and k < len(node):
            yield from (((k, *p), v) for p, v in _at(node[k], rest, got))


def _without(node: JsonValue, path: KeyPath) -> JsonValue:
    """`node` without the entry at `path`, copied along the path only (the caller's
    document stays as read)."""
    step, rest = path[0], path[1:]
    if isinstance(node, list) and isinstance(step, int):
        items = list(node)
        items[step:step + 1] = [_without(node[step], rest)] if rest else []
        return items
    if isinstance(node, dict) and isinstance(step, str):
        keys = {k: _without(v, rest) if rest and k == step else v
                for k, v in node.items() if rest or k != step}
        return keys
    return node


def decode(node: JsonValue, model: type[S], *, strict: bool, leaves: bool = False,
           root: KeyPath = ()) -> tuple[S, JsonValue, list[str]]:
    """`node` (at `root` in result.json) as `model`, the value as read with what was
    dropped, named, taken out, and those names. msgspec decodes; what it refuses is taken
    out and decoding tried again, so a field's default reads "not stated": a container (a
    mapping or a list where one belongs) or a list's entry is named, a leaf of the wrong
    type too when `leaves`, a key that is null (absent) never; an entry lacking a key its
    model needs goes whole. `strict`: MalformedResult at the first refusal that would be
    named. The node itself malformed: MalformedResult."""
    dropped: list[str] = []
    kept = node
    nulled: KeyPath = ()      # a number just taken out as null: its entry then goes
    while True:
        try:
            return msgspec.convert(node, model, strict=True), kept, dropped
        except msgspec.ValidationError as err:
            at, problem = problem_of(err)
            m = _EXPECTED.match(str(err))
            want, got = (m["want"], m["got"]) if m else ("", "")
            steps: list[str | int] = [s["key"] or (
                s["index"] if s["index"] == "..." else int(s["index"]))
                for s in _STEP.finditer(at)]
            if problem == "missing":
                want, got, key = "object", "", steps.pop()
            path, value = next(_at(node, steps, got), ((), None))
            if not path:
                raise MalformedResult(where((*root, *steps)) or layout.RESULT, problem
                                      ) from None
            keyed = isinstance(path[-1], str)
            if problem == "missing":
                problem = f"no numeric {key}" if nulled == (*path, key) else f"no {key}"
            elif (value is not None or not keyed) and ("object" in want or "array" in want):
                shape = "a mapping" if "object" in want else "a list"
                problem = f"expected {shape}, found {type(value).__name__}"
            elif keyed and (value is None or not leaves):
                nulled = path if value is None and ("float" in want or "int" in want) else ()
                node = _without(node, path)     # unnamed: the value as read keeps it
                continue
            if strict:
                raise MalformedResult(where((*root, *path)), problem) from None
            dropped.append(f"{where((*root, *path))} ({problem})")
            node, kept = _without(node, path), _without(kept, path)


# -- the frame -------------------------------------------------------------------------------

class Check(msgspec.Struct, frozen=True, kw_only=True):
    """One conformity check (bench.report.conformity): what was judged and the verdict;
    `doc`: every key, in result.json's order (a kind's figures under unit-suffixed keys)."""

    axis: str | None = None
    quantity: str | None = None
    verdict: str | None = None
    set_rate_dps: int | float | None = None
    rule: str | None = None
    one_sided: bool = False   # an unresolved value, judged on its upper limit
    upper_rel: int | float | None = None   # the 97.5 % limit (or the interval's upper end)
    lower_rel: int | float | None = None   # the interval's lower end of an asymmetric value
    capability_ratio: int | float | None = None   # U/T (RMG 63-2003)
    capability_ok: bool | None = None
    reason: str | None = None    # why the verdict is not a pass
    #: what an unresolved value was not resolved above ('timing floor', 'FOG floor':
    #: docs/method.md D2), as the kind names it
    floor_name: str | None = None
    tolerance_rel: int | float | None = None  # a relative quantity's (None: °/h, °/s...)
    doc: dict[str, Json] = msgspec.field(default_factory=dict, name="(doc)")

    @property
    def tolerance(self) -> float | None:
        """The tolerance, in the unit its key names (tolerance_rel, tolerance_dph...), as
        stated (an int stays an int: the records store it so); None when no finite number."""
        found = next((self.doc[k] for k in ("tolerance_rel", "tolerance_dph", *sorted(
            self.doc)) if k.startswith("tolerance") and k in self.doc), None)
        if isinstance(found, bool) or not isinstance(found, int | float):
            return None
        return found if math.isfinite(found) else None

    @classmethod
    def of(cls, doc: JsonObject) -> Check:
        """A check a kind states by its keys (what of them is malformed left out)."""
        return msgspec.structs.replace(decode(doc, cls, strict=False)[0], doc=doc)

    def figure(self, key: str) -> float | None:
        """A figure the check states under a unit-suffixed key (`U_rel`, `tolerance_dph`,
        `upper_rel`...: which ones depends on the quantity's unit), read as the DCC always
        read them (numeric text too); None when absent or no finite number."""
        return finite_number(self.doc.get(key))

    def states(self, key: str) -> bool:
        """Whether the check states `key` at all (the quantity's unit is named by which
        `value_<unit>` it holds)."""
        return key in self.doc


#: a node of a result as a reader walks it: result.json's JSON, or (a result its analysis
#: has just given) the kind's own model, read by its attributes
Node: TypeAlias = JsonLike | msgspec.Struct | Sequence["Node"] | Mapping[str, "Node"]


def entries(node: Node) -> Iterator[tuple[str | int, Node]]:
    """What `node` states, as result.json holds it: a mapping's entries, a list's items
    (by index), a model's fields under their keys, those its encoding leaves out (UNSET;
    a default an `omit_defaults` model omits) left out."""
    if isinstance(node, msgspec.Struct):
        names = node.__struct_fields__
        # the defaults stand for the last fields (msgspec's layout; its `structs.fields`
        # would evaluate every annotation, some named for the type checker only)
        defaults = (msgspec.NODEFAULT,) * (len(names) - len(node.__struct_defaults__)) \
            + node.__struct_defaults__
        omit = node.__struct_config__.omit_defaults
        for name, key, default in zip(names, node.__struct_encode_fields__, defaults,
                                      strict=True):
            value = getattr(node, name)
            factory = getattr(default, "factory", None)
            if value is UNSET or omit and default is not msgspec.NODEFAULT and \
                    value == (factory() if factory is not None else default):
                continue
            yield key, value
    elif isinstance(node, Mapping):
        yield from node.items()
    elif isinstance(node, list | tuple):
        yield from enumerate(node)


def at(node: Node, *keys: str | int) -> Node:
    """The value at `keys` under `node`, as result.json states it; None when it states none."""
    for key in keys:
        node = dict(entries(node)).get(key)
    return node


def _stated(part: Body) -> dict[str, Json]:
    """A kind's part by its keys, the values as they are (no encoding)."""
    return {str(k): cast(Json, v) for k, v in entries(part)}


def _check(check: Body) -> Check:
    """A kind's check as its analysis gave it: a model's fields taken as they are (its
    keys, for the figures under unit-suffixed ones), a plug-in kind's JSON values read."""
    stated = _stated(check)
    if not isinstance(check, msgspec.Struct):
        return Check.of(stated)
    fields = {k: v for k, v in stated.items() if k in Check.__struct_fields__}
    return Check(**fields, doc=stated)  # type: ignore[arg-type] # the kind's typed values


class MeasuredHalf(msgspec.Struct, frozen=True):
    """The FOG's temperature over one half, from its frames (`conditions_measured.
    fog_temperature.axes.<axis>.halves[]`, procedures that record it)."""

    half: int | float | None = None
    set_rate_dps: int | float | None = None
    min_c: int | float | None = None
    mean_c: int | float | None = None
    max_c: int | float | None = None


class FogAxisTemperature(msgspec.Struct, frozen=True):
    """The FOG's temperature over all of one axis's halves, from its frames
    (`conditions_measured.fog_temperature.axes.<axis>`), and per half."""

    min_c: int | float | None = None
    mean_c: int | float | None = None
    max_c: int | float | None = None
    halves: tuple[MeasuredHalf, ...] = ()


class FogTemperature(msgspec.Struct, frozen=True):
    axes: dict[str, FogAxisTemperature] | None = None


class MeasuredConditions(msgspec.Struct, frozen=True):
    """What the bench measured of the conditions itself (`conditions_measured`): the room
    where a sensor said so, the FOG's temperature per axis; empty when it measured none."""

    room: dict[str, Json] | None = None
    fog_temperature: FogTemperature | None = None

    @property
    def fog_axes(self) -> dict[str, FogAxisTemperature]:
        return (self.fog_temperature.axes if self.fog_temperature else None) or {}

    @property
    def fog_halves(self) -> dict[str, tuple[MeasuredHalf, ...]] | None:
        """Per axis, the halves' FOG temperatures the run measured; None when it measured
        none."""
        axes = self.fog_temperature.axes if self.fog_temperature else None
        return None if axes is None else {a: t.halves for a, t in axes.items()}


class Specification(msgspec.Struct, frozen=True):
    """Where the procedure's tolerances come from (`specification`: a datasheet, a
    standard) and what its quantities mean there; a certificate without one says so."""

    source: Json = None        # as written (text_of prints it); falsy: not identified
    definitions: dict[str, Json] = {}  # quantity key -> its definition in the source

    @classmethod
    def of(cls, value: object) -> Specification | None:
        """A procedure file's specification; None when it states none."""
        doc = as_object(value)
        return cls(doc.get("source"), obj(doc, "definitions")) if doc else None


class HashedFile(msgspec.Struct, frozen=True):
    """A file and its SHA-256 as the run recorded it (`raw_files[]`): printed as written,
    its byte count read as the certificate always read it (numeric text too)."""

    path: Json = None
    sha256: Json = None
    bytes: Json = None

    @property
    def size_bytes(self) -> float | None:
        return finite_number(self.bytes)


class ProcedureFile(msgspec.Struct, frozen=True):
    """result.json's `procedure_file`: the procedure file's name and SHA-256, as written."""

    name: Json = None
    sha256: Json = None


class RunDates(msgspec.Struct, frozen=True):
    """When the run was created, first started and last ended (`dates`), as written."""

    created_utc: str | None = None
    started_utc: str | None = None
    completed_utc: str | None = None


class RunSession(msgspec.Struct, frozen=True):
    """One session of the run and how it ended (`run_sessions[]`, bench.core.journal's
    SessionEnding): a resume is a session of the same run."""

    session: int | None = None
    started_utc: str | None = None
    ended_utc: str | None = None
    ended: str | None = None     # completed, aborted, refused, killed or crashed; None: running
    performer: str | None = None
    os_user: str | None = None


#: the frame's blocks a reader prints as written, key by key (the procedure's and the stand's
#: free-form YAML, the kind's settings): not typed beyond a mapping
AS_WRITTEN = ("stand", "instruments", "conditions", "specification", "certificate",
              "method")


class ResultFrame(msgspec.Struct, frozen=True, kw_only=True):
    """What every kind's result.json says about the run (bench.report.codec.ResultHead):
    the header, the decision rule, the method, the checks and the verdict. Every part is
    optional: a hand-made or older result may lack it, and the certificate says so."""

    schema: str | None = None
    procedure: str | None = None
    verdict: str | None = None
    title: str | None = None
    run_dir: str | None = None
    procedure_file: ProcedureFile = ProcedureFile()
    stand: dict[str, Json] = {}
    instruments: dict[str, dict[str, Json]] = {}
    dates: RunDates = RunDates()
    conditions: dict[str, Json] | None = None
    conditions_measured: MeasuredConditions = MeasuredConditions()
    specification: Specification | None = None
    certificate: dict[str, Json] = {}   # the settings (the lab file's under the run's)
    sessions: int | None = None
    run_sessions: tuple[RunSession, ...] = ()
    aborted: bool = False
    ended: str | None = None        # how the last session ended (None: no word yet)
    deviations: tuple[Json, ...] = ()   # a result's own deviations (hand-made or older ones)
    raw_files: tuple[HashedFile, ...] = ()
    decision_rule: str | None = None
    method: dict[str, Json] = {}
    checks: tuple[Check, ...] = ()
    records: dict[str, Json] = {}    # what the run says for the records (calibration state)
    #: the whole document as written, in result.json's order (not a key of it)
    doc: dict[str, Json] = msgspec.field(default_factory=dict, name="(doc)")
    #: the kind's body as its analysis gave it (None: read from a file)
    body: Body = msgspec.field(default=None, name="(body)")

    @classmethod
    def conform(cls, doc: object) -> tuple[ResultFrame, list[str]]:
        """The frame with malformed containers dropped, and the list of what was dropped."""
        top = as_object(doc)
        if top is None:
            return cls(), ["result.json (expected a mapping)"]
        return cls._decoded(top, strict=False)

    @classmethod
    def from_json(cls, doc: object) -> ResultFrame:
        """The frame, or MalformedResult naming the first malformed key path."""
        top = as_object(doc)
        if top is None:
            raise MalformedResult(layout.RESULT, "is not a JSON object")
        return cls._decoded(top, strict=True)[0]

    @classmethod
    def of(cls, doc: JsonObject) -> ResultFrame:
        """The frame of a document kept as read (the records digest it), what is
        malformed in it left out of the frame unnamed."""
        return msgspec.structs.replace(cls.conform(doc)[0], doc=doc)

    @classmethod
    def _decoded(cls, top: JsonObject, *, strict: bool) -> tuple[ResultFrame, list[str]]:
        frame, found, dropped = decode(top, cls, strict=strict)
        doc = cast(JsonObject, found)
        written = doc.get("checks")
        checks = tuple(msgspec.structs.replace(c, doc=as_object(d) or {}) for c, d in zip(
            frame.checks, written if isinstance(written, list) else (), strict=False))
        return msgspec.structs.replace(frame, checks=checks, doc=doc), dropped

    @classmethod
    def analysed(cls, head: msgspec.Struct, body: Body, document: JsonObject) -> ResultFrame:
        """The frame of a result its analysis has just given: its head's and body's own
        attributes (msgspec reads them), no JSON in between. `document` is its encoding:
        the records digest and store it, and the blocks the frame only prints as written
        (`AS_WRITTEN`: free-form YAML, the kind's settings) are its, as a file's reader
        prints them (a list, not the model's tuple)."""
        measured = getattr(body, "conditions_measured", None)
        blocks = {k: document[k] for k in AS_WRITTEN if k in document}
        frame = msgspec.convert(msgspec.structs.replace(head, checks=(), **blocks), cls,
                                from_attributes=True)
        return msgspec.structs.replace(
            frame, checks=tuple(map(_check, getattr(head, "checks", ()))),
            conditions_measured=MeasuredConditions() if measured in (None, UNSET) else
            msgspec.convert(measured, MeasuredConditions, from_attributes=True),
            doc=document, body=body)

    @property
    def corrections(self) -> tuple[Correction, ...]:
        """The instrument corrections it applied (issue 58)."""
        return corrections_of(self.doc)

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


class CertificateSettings(msgspec.Struct, frozen=True):
    """The certificate settings (`certificate`: the lab file's under the run's): who
    issues it and for whom; each printed as written (an absent one says so)."""

    laboratory: Json = None
    address: Json = None
    accreditation: Json = None
    customer: Json = None
    customer_address: Json = None
    customer_contact: Json = None
    site: Json = None
    #: every setting, in the file's order (not a key of it)
    entries: tuple[tuple[str, Json], ...] = msgspec.field(default=(), name="(entries)")

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
        named = {k: v for k, v in doc.items() if isinstance(k, str)}  # a YAML key may not be
        return msgspec.structs.replace(msgspec.convert(named, cls), entries=tuple(doc.items()))


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


