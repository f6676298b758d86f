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

import copy
import math
import re
from pathlib import Path
from typing import Annotated

import msgspec

from bench.core import rundir_layout as layout
from bench.core.journal_codec import read_jsonl
from bench.report.certificate.parts import Sources
from bench.report.codec import as_written, problem_of
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
)
from procedures.rate_ladder.result import LadderAxis, LadderBody, LadderResult

#: the body's key in result.json, and the root of every path a refusal names
ROOT = "axes"

_STEP = re.compile(r"\.(?P<key>[A-Za-z_][A-Za-z0-9_]*)|\[(?P<index>\d+)\]")


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




def _axis(name: str, node: JsonValue) -> LadderAxis:
    try:
        return msgspec.convert(node, LadderAxis, strict=True)
    except msgspec.ValidationError as err:
        path, problem = problem_of(err)
        raise MalformedResult(f"{ROOT}.{name}{path}", problem) from None


def _drop(node: JsonValue, path: str) -> bool:
    """Remove the entry at `path` (msgspec's `.key[0].key` below an axis, every step but
    the last one there) from `node`: a key of an object (its default then reads "not
    stated") or, for a missing key, the object holding it from its list. False when there
    is nothing to remove."""
    steps: list[str | int] = [m["key"] if m["key"] else int(m["index"])
                              for m in _STEP.finditer(path)]
    chain = [node]
    for step in steps[:-1]:
        at = chain[-1]
        chain.append(at[step] if isinstance(at, list) and isinstance(step, int) else
                     at.get(step) if isinstance(at, dict) and isinstance(step, str) else None)
    if steps and isinstance(at := chain[-1], dict) and steps[-1] in at:
        del at[steps[-1]]
        return True
    # a required key missing: the item holding it goes from its list
    lists = [(p, i) for p, i in zip(chain[:-1], steps, strict=False)
             if isinstance(p, list) and isinstance(i, int)]
    if lists:
        del lists[-1][0][lists[-1][1]]
    return bool(lists)


def _lenient_axis(name: str, node: JsonValue, dropped: list[str]) -> JsonValue:
    """A copy of an axis with its malformed entries dropped (named in `dropped`), None if
    nothing of it is readable."""
    node = copy.deepcopy(node)     # the caller's document stays as read
    for _ in range(1000):     # one entry dropped per round; a body has fewer
        try:
            msgspec.convert(node, LadderAxis, strict=True)
            return node
        except msgspec.ValidationError as err:
            path, problem = problem_of(err)
            dropped.append(f"{ROOT}.{name}{path} ({problem})")
            if not _drop(node, path):
                return None
    return None


def _axes_node(doc: JsonObject) -> dict[str, JsonValue]:
    found = as_object(doc.get(ROOT))
    return {} if found is None else {k: v for k, v in found.items() if isinstance(v, dict)}


def ladder_of(doc: object) -> LadderResult:
    """A whole result.json decoded once, or MalformedResult naming the first malformed key
    path."""
    top = as_object(doc)
    if top is None:
        raise MalformedResult(layout.RESULT, "is not a JSON object")
    issues = Issues(strict=True)
    top = conform_frame(conform_ladder(top, issues), issues)
    return LadderResult(frame=ResultFrame.of(top),
                        axes={name: _axis(name, a) for name, a in _axes_node(top).items()})


def conform_body(doc: JsonObject) -> tuple[JsonObject, list[str]]:
    """result.json with the malformed parts of its ladder body dropped, and what was
    dropped (named): what the certificate prints, and its section Deviations lists."""
    issues = Issues(strict=False)
    top = conform_ladder(dict(doc), issues)
    dropped = issues.dropped
    if ROOT in top:
        top[ROOT] = {name: found for name, a in _axes_node(top).items()
                     if (found := _lenient_axis(name, a, dropped)) is not None}
    return top, dropped


def conform(doc: object) -> tuple[LadderResult, list[str]]:
    """A whole result.json with its malformed parts dropped, decoded, and what was dropped."""
    top = as_object(doc)
    if top is None:
        return LadderResult(frame=ResultFrame.of({}), axes={}), [
            "result.json (expected a mapping)"]
    body, dropped = conform_body(top)
    frame_issues = Issues(strict=False)
    body = conform_frame(body, frame_issues)
    return ladder_of(body), dropped + frame_issues.dropped


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
