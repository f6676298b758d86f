"""result.json's drift parts <-> the drift kind's result model (result.py), by msgspec.

Why a module of its own: it is the one place of the kind where a JSON value meets the model
(tests/test_json_boundary.py keeps JSON maps out of every other module). Encoding gives
the builtins `json.dumps` writes (bench/report/codec.py: the result writer's floats, so the
file's bytes are those of before); decoding refuses a malformed body naming the key path in result.json's terms
(`drift.axes.x.positions[1].mean_dph: missing`), so a certificate is never built from half
a result.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, TypeVar

import msgspec

from bench.core import rundir_layout as layout
from bench.core.journal import RunDir
from bench.report.certificate.parts import Sources
from bench.report.codec import as_written, problem_of
from bench.report.codec import encode as encode
from bench.report.result_frame import ResultFrame
from drivers.json_types import JsonValue
from procedures.drift_pulse.result import AxisFigures, DriftBody, DriftFigures

#: the body's key in result.json, and the root of every path a refusal names
ROOT = "drift"

S = TypeVar("S", bound=msgspec.Struct)



class MalformedResult(ValueError):
    """A result.json drift body that does not hold what the analysis writes."""

    def __init__(self, path: str, problem: str) -> None:
        super().__init__(f"result.json {path}: {problem}")
        self.path = path


def _refusal(err: msgspec.ValidationError, node: object, root: str) -> MalformedResult:
    """msgspec's `Expected `float`, got `str` - at `$.axes[...].own_dph`` in result.json's
    words, the axis named (msgspec does not name a mapping's keys)."""
    path, found = problem_of(err)
    if path.startswith(".axes[...]") and isinstance(node, dict) \
            and isinstance(axes := node.get("axes"), dict):
        for name, axis in axes.items():
            try:
                msgspec.convert(axis, AxisFigures, strict=True)
            except msgspec.ValidationError:
                path = f".axes.{name}" + path[len(".axes[...]"):]
                break
    return MalformedResult(f"{root}{path}", found)


def decode(node: object, model: type[S], root: str = ROOT) -> S:
    """`node` as `model`, or MalformedResult naming the first malformed key path."""
    try:
        return msgspec.convert(node, model, strict=True)
    except msgspec.ValidationError as err:
        raise _refusal(err, node, root) from None


def drift_of(result: Mapping[str, object]) -> DriftFigures:
    """The drift body of a whole result.json, decoded once for a reader."""
    if ROOT not in result:
        raise MalformedResult(ROOT, "missing")
    return decode(result[ROOT], DriftFigures)


def drift_in(frame: ResultFrame) -> DriftFigures:
    """The drift figures of a result: the analysis's own when it has just given them
    (`KindResult.frame`, which holds the body only when it is what result.json holds),
    else the file's, decoded (MalformedResult naming what is not)."""
    if isinstance(frame.body, DriftBody):
        return frame.body.drift
    return drift_of(frame.doc)


def drift_model(src: Sources) -> DriftFigures:
    """The certificate's and the DCC's drift figures: `src.model(drift_model)` gives them
    once for every section. A result the analysis has just given (`Sources.analysed`) is
    its model already, when it holds what result.json holds; else result.json's, decoded."""
    body = src.body
    if isinstance(body, DriftBody) and not src.dropped and as_written(body.drift):
        return body.drift
    return drift_of(src.result)


class Correction(msgspec.Struct, frozen=True):
    """One entry of the run folder's corrections file (issue 58, procedures/drift_pulse/
    corrections.py): the item's place, the quantity, its value, its expanded uncertainty U
    (k = 2; null: none stated) and the item's serial."""

    where: str = ""
    quantity: str = ""
    value: float = math.nan
    U: Annotated[float, msgspec.Meta(ge=0.0)] | None = None     # noqa: N815
    serial: str | int | None = None


#: a correction's number at fault, and what it should be
_NUMBER = re.compile(r"\.corrections\[(?P<i>\d+)\]\.(?P<key>value|U)")
_WANT = {"value": "a finite number", "U": "a finite number >= 0 or null"}


class _CorrectionsFile(msgspec.Struct, frozen=True):
    corrections: tuple[Correction, ...]


def corrections_file(path: Path) -> list[tuple[Correction, JsonValue]]:
    """Each entry of the corrections file decoded, beside it as written (result.json states
    the applied ones so); a torn file or an entry of the wrong type raises ValueError naming
    the file and the key (`corrections[0].U: expected a number >= 0.0`)."""
    try:
        doc = msgspec.json.decode(path.read_bytes())
    except msgspec.DecodeError as e:
        raise ValueError(f"{path}: not JSON: {e}") from None
    try:
        found = msgspec.convert(doc, _CorrectionsFile, strict=True)
    except msgspec.ValidationError as err:
        refused = _refusal(err, doc, "")
        problem = str(refused).removeprefix(f"result.json {refused.path}: ")
        if (m := _NUMBER.fullmatch(refused.path)) and isinstance(doc["corrections"][
                i := int(m["i"])], dict):       # the file's words: what it should hold
            problem = f"{_WANT[m['key']]}, got {doc['corrections'][i].get(m['key'])!r}"
        raise ValueError(f"{path}: {refused.path.lstrip('.')}: {problem}") from None
    return list(zip(found.corrections, doc["corrections"], strict=True))


def dmm_replies(run: RunDir, session: int, gyro: str, model: str) -> list[str]:
    """The DMM's replies to FETC?, in order, from its raw SCPI journal of a session (JSON
    lines, read here as the kind's other JSON is)."""
    from bench.core.journal_codec import read_jsonl, str_field
    from drivers.dmm import PROFILES as DMM_PROFILES
    path = layout.raw_file(run.path, session, layout.dmm_log(gyro))
    out, waiting = [], False
    fetch = DMM_PROFILES[model].words.fetch.text().upper()
    for r in read_jsonl(path):
        if r.get("dir") == "tx":
            waiting = str_field(r, "data").strip().upper() == fetch
        elif r.get("dir") == "rx" and waiting:
            out.append(str_field(r, "data"))
            waiting = False
    return out
