"""A run's result as the analysis returns it (`KindResult`: the shared frame and the kind's
body, typed) and as result.json's writer takes it (issue 60).

Why one codec for every kind: the analysis hands its typed result to the session, which
writes result.json from it (`document`) and gives the same value to the certificate, the
records and the register, so nothing reads the file it has just written back.

Why not msgspec's own JSON encoder: it writes floats in its own shortest form (1e-05 as
0.00001), and result.json's bytes are `json.dumps`' (the writer in bench/core/journal.py);
so a model is turned into builtins in its Structs' field order, and the writer writes them
as before.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Generic, TypeAlias, TypeVar, cast

import msgspec

from bench.core.yamlfile import YamlValue
from bench.report.result_frame import ResultFrame
from bench.report.result_frame import problem_of as problem_of
from drivers.json_types import JsonLike, JsonObject, JsonScalar, JsonValue

#: a part of result.json a kind gives: its Struct, or (a plug-in kind's) JSON values
ResultPart: TypeAlias = msgspec.Struct | Mapping[str, JsonLike]
#: the kind's body: what follows the frame in result.json (its Struct's fields, in order)
B = TypeVar("B", bound=msgspec.Struct | Mapping[str, JsonLike], covariant=True)


class ProcedureFileRef(msgspec.Struct, frozen=True):
    """result.json's `procedure_file`: the procedure the run followed, by name and digest."""

    name: str
    sha256: str


class RunDates(msgspec.Struct, frozen=True):
    """result.json's `dates`: made, first started, last ended (None: not yet)."""

    created_utc: str
    started_utc: str | None
    completed_utc: str | None


class RawFile(msgspec.Struct, frozen=True):
    """result.json's `raw_files` entry: a raw file of the run, as hashed."""

    path: str
    sha256: str
    bytes: int


class ResultHead(msgspec.Struct, frozen=True, kw_only=True):
    """What every kind's result.json says first, in the document's key order
    (bench/report/result_frame.py reads it back as ResultFrame): the schema, the verdict,
    the run header, the decision rule, the method and the checks."""

    schema: str
    uncertainty_names: str
    procedure: str
    verdict: str
    title: str
    run_dir: str
    procedure_file: ProcedureFileRef
    #: the stand file's identity keys it states, then the file, its digest, simulated
    stand: dict[str, JsonScalar]
    instruments: dict[str, dict[str, str]]
    dates: RunDates
    # the procedure's free-form blocks as its file states them (YAML values)
    conditions: dict[str, YamlValue]
    specification: dict[str, YamlValue] | None
    certificate: dict[str, YamlValue]
    sessions: int
    aborted: bool
    ended: str | None
    run_sessions: list[dict[str, str | int | None]]
    raw_files: list[RawFile]
    decision_rule: str
    decision_rule_text: str
    method: ResultPart
    checks: Sequence[ResultPart]


@dataclass(frozen=True)
class KindResult(Generic[B]):
    """A run's result: the shared frame and the kind's body (a Struct whose fields are
    result.json's keys after the frame), as the kind's analysis returns it."""

    head: ResultHead
    body: B

    @property
    def verdict(self) -> str:
        return self.head.verdict

    @cached_property
    def document(self) -> JsonObject:
        """result.json as its writer takes it (encoded once)."""
        return {**written(self.head), **written(self.body)}

    @cached_property
    def frame(self) -> ResultFrame:
        """The frame every reader of a result takes (records, register, station): the
        head's and body's own values when they hold what result.json holds (no NaN, no
        numpy number), else its encoding's (`as_written`)."""
        if as_written(self.head) and as_written(self.body):
            return ResultFrame.analysed(self.head, self.body, self.document)
        return ResultFrame.of(self.document)


def _builtin(value: object) -> object:
    """A numpy scalar as the Python number it holds (json.dumps writes both alike)."""
    item = getattr(value, "item", None)
    if callable(item):
        return item()
    raise NotImplementedError(f"{type(value).__name__} is no JSON value")


def _lists(value: object) -> JsonValue:
    """msgspec's builtins keep a tuple a tuple; JSON's arrays are lists (as `json.load`
    gives them back, so a reader of the document in memory sees what a reader of the file
    does)."""
    if isinstance(value, tuple | list):
        return [_lists(v) for v in value]
    if isinstance(value, dict):
        return {k: _lists(v) for k, v in value.items()}
    return cast(JsonValue, value)


def _finite(value: JsonValue) -> JsonValue:
    """Non-finite floats as null, recursively (JSON has no NaN: result.json's writer
    refuses one, so a document it wrote never held one)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, list):
        return [_finite(v) for v in value]
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    return value


def encode(model: msgspec.Struct | Mapping[str, JsonLike]) -> JsonObject:
    """A model part as result.json's writer takes it: builtins in the Structs' field order."""
    return cast(JsonObject, _lists(msgspec.to_builtins(model, enc_hook=_builtin)))


def written(model: msgspec.Struct | Mapping[str, JsonLike]) -> JsonObject:
    """A model part as result.json holds it, as `json.load` gives it back: `encode`'s, a
    non-finite number as null, a number as a key as text (a YAML block's `1: ...`)."""
    return cast(JsonObject, _finite(_lists(msgspec.to_builtins(model, enc_hook=_builtin,
                                                               str_keys=True))))


def as_written(value: msgspec.Struct | JsonLike | Mapping[str, msgspec.Struct]
               | msgspec.UnsetType) -> bool:
    """Whether a model part holds only what its encoding holds (finite Python numbers, no
    numpy scalar): then the analysis's own model is what decoding result.json gives back,
    and a reader may take it as it is (`Sources.analysed`; the kinds' `*_model`)."""
    if isinstance(value, msgspec.Struct):
        return all(as_written(getattr(value, f)) for f in value.__struct_fields__)
    if isinstance(value, tuple | list):
        return all(as_written(v) for v in value)
    if isinstance(value, Mapping):    # a number key is text in the file
        return all(isinstance(k, str) and as_written(v) for k, v in value.items())
    if isinstance(value, float):
        return type(value) is float and math.isfinite(value)
    return value is None or value is msgspec.UNSET or type(value) in (int, bool, str)
