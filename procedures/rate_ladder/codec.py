"""result.json's ladder body <-> the rate ladder's result model (result.py), by msgspec.

Why a module of its own: it is the one place of the kind where a JSON value meets the model
(tests/test_json_boundary.py keeps JSON maps out of every other module). Encoding gives the
builtins `json.dumps` writes (bench/report/codec.py: the result writer's floats, so the
file's bytes are those of before), non-finite numbers as null (JSON has no NaN); decoding
refuses a malformed body naming the key path in result.json's terms
(`axes.outer.rates[0].turns: expected an integer, got str`), or, for the certificate,
drops the malformed part, names it and keeps the rest (`conform`).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import msgspec

from bench.core import rundir_layout as layout
from bench.core.journal_codec import read_jsonl
from bench.report.certificate.parts import Sources
from bench.report.codec import as_written, problem_of
from bench.report.result_frame import (
    JsonObject,
    JsonValue,
    MalformedResult,
    ResultFrame,
    as_object,
    decode,
)
from procedures.rate_ladder.result import LadderAxis, LadderBody, LadderResult

#: the body's key in result.json, and the root of every path a refusal names
ROOT = "axes"


def _axes_node(doc: JsonObject, dropped: list[str] | None = None) -> dict[str, JsonValue]:
    """The axes a result states, each a mapping: in `dropped` (else refused: MalformedResult)
    what is not; null, absent."""
    found = doc.get(ROOT)
    shape = (f"{ROOT}", found) if not isinstance(found, dict | None) else None
    axes = found if isinstance(found, dict) else {}
    bad = [shape] if shape else []
    bad += [(f"{ROOT}.{k}", v) for k, v in axes.items() if not isinstance(v, dict | None)]
    for where, value in bad:
        if dropped is None:
            raise MalformedResult(where, f"expected a mapping, found {type(value).__name__}")
        dropped.append(f"{where} (expected a mapping, found {type(value).__name__})")
    return {k: v for k, v in axes.items() if isinstance(v, dict)}


def ladder_of(doc: object) -> LadderResult:
    """A whole result.json decoded once, or MalformedResult naming the first malformed key
    path."""
    top = as_object(doc)
    if top is None:
        raise MalformedResult(layout.RESULT, "is not a JSON object")
    axes = {name: decode(a, LadderAxis, strict=True, leaves=True, root=(ROOT, name))[0]
            for name, a in _axes_node(top).items()}
    return LadderResult(frame=ResultFrame.from_json(top), axes=axes)


def _lenient(top: JsonObject) -> tuple[JsonObject, dict[str, LadderAxis], list[str]]:
    """The document with the malformed parts of its ladder body dropped, its axes, and
    what was dropped (named)."""
    dropped: list[str] = []
    nodes: dict[str, JsonValue] = {}
    axes: dict[str, LadderAxis] = {}
    for name, a in _axes_node(top, dropped).items():
        try:
            axes[name], nodes[name], more = decode(a, LadderAxis, strict=False, leaves=True,
                                                   root=(ROOT, name))
            dropped += more
        except MalformedResult as e:     # nothing of the axis readable
            dropped.append(f"{e.path} ({e.problem})")
    return ({**top, ROOT: nodes} if ROOT in top else top), axes, dropped


def conform_body(doc: JsonObject) -> tuple[JsonObject, list[str]]:
    """result.json with the malformed parts of its ladder body dropped, and what was
    dropped (named): what the certificate prints, and its section Deviations lists."""
    top, _, dropped = _lenient(doc)
    return top, dropped


def conform(doc: object) -> tuple[LadderResult, list[str]]:
    """A whole result.json with its malformed parts dropped, decoded, and what was dropped."""
    frame, more = ResultFrame.conform(doc)
    _, axes, dropped = _lenient(frame.doc)
    return LadderResult(frame=frame, axes=axes), dropped + more


def axes_in(frame: ResultFrame) -> dict[str, LadderAxis]:
    """The ladder's axes of a result: the analysis's own when it has just given them
    (`KindResult.frame`, which holds the body only when it is what result.json holds),
    else the file's, decoded, what is malformed in them left out."""
    if isinstance(frame.body, LadderBody):
        return frame.body.axes
    return _lenient(frame.doc)[1]


def ladder_model(src: Sources) -> LadderResult:
    """The certificate's and the DCC's model of the (conformed) result: `src.model(
    ladder_model)` decodes it once for every section. A result the analysis has just
    given (`Sources.analysed`) is its model already, when it holds what result.json holds
    (no NaN, no numpy number: then decoding its encoding gives it back)."""
    body = src.body
    if isinstance(body, LadderBody) and not src.dropped and as_written(body.axes):
        return LadderResult(frame=src.frame, axes=body.axes)
    return ladder_of(src.result)


# -- the run folder's inputs: the counter's raw log, the corrections file ---------------------

class CounterReply(msgspec.Struct, frozen=True):
    """One line of a counter's raw log (bench/core/instruments.py): its direction and
    text; any other key of the line is not the analysis's."""

    dir: str = ""
    data: str | None = None


def counter_replies(path: Path) -> list[CounterReply]:
    """A counter's raw log, line by line (a torn line is skipped, a line whose direction
    or text is not text reads as neither)."""
    out = []
    for rec in read_jsonl(path):
        try:
            out.append(msgspec.convert(rec, CounterReply))
        except msgspec.ValidationError:
            out.append(CounterReply())
    return out


class Correction(msgspec.Struct, frozen=True):
    """One entry of the run folder's corrections file (issue 58): the item's place, the
    quantity, its value and expanded uncertainty U (k = 2; null: none stated)."""

    where: str = ""
    quantity: str = ""
    value: float = math.nan
    U: Annotated[float, msgspec.Meta(ge=0.0)] | None = None     # noqa: N815


class CorrectionsFile(msgspec.Struct, frozen=True):
    corrections: tuple[Correction, ...] = ()


def read_corrections(path: Path) -> tuple[tuple[Correction, ...], JsonValue]:
    """The corrections file's entries decoded, and as written (result.json states them
    so); a torn file or an entry of the wrong type raises ValueError naming the file and
    the key (`corrections[0].value: expected a number, got str`)."""
    try:
        doc = msgspec.json.decode(path.read_bytes())
    except msgspec.DecodeError as e:
        raise ValueError(f"{path}: not JSON: {e}") from None
    try:
        found = msgspec.convert(doc, CorrectionsFile)
    except msgspec.ValidationError as err:
        where, problem = problem_of(err)
        raise ValueError(f"{path}: {where.lstrip('.')}: {problem}") from None
    return found.corrections, doc.get("corrections")
