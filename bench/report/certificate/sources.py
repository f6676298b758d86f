"""The run directory as the certificate and the DCC read it, decoded once: result.json
(conformed: its malformed parts dropped and named), meta.json, the run's copies of the
stand and procedure files, and the event log (`Sources`).

Why a codec of its own (tests/json_boundary.py's CODECS): this is where the report meets
the run directory's JSON; every section then reads the typed frame (`Sources.frame`,
bench/report/result_frame.py) and the kind's model (`Sources.model`), decoded here on first
use. A damaged meta.json reads as empty (the certificate says "not recorded"), never as a
crash that leaves the operator without a certificate.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, Protocol, TypeVar, cast, runtime_checkable

import msgspec

from bench.core import events as ev
from bench.core import rundir_layout as layout
from bench.core.events import Event
from bench.core.journal import read_events
from bench.core.journal_codec import StartMeta, start_meta
from bench.core.placeholders import run_copy
from bench.report.codec import KindResult, ResultPart
from bench.report.result_frame import JsonObject, ResultFrame, as_object
from drivers.json_types import JsonScalar

M = TypeVar("M")


class StandIdentity(msgspec.Struct, frozen=True, kw_only=True):
    """The stand's identity as the certificate and the DCC print it (`Sources.stand`):
    each value as written (a serial may be a number), None where nothing states it."""

    maker: JsonScalar = None
    model: JsonScalar = None
    serial: JsonScalar = None
    location: JsonScalar = None
    file: JsonScalar = None
    sha256: JsonScalar = None
    simulated: JsonScalar = None


@dataclass
class Sources:
    """result.json and whatever the run directory adds to it."""

    result: JsonObject
    run_path: Path | None = None
    meta: JsonObject = field(default_factory=dict)
    stand_file: dict[str, Any] = field(default_factory=dict)
    procedure_file: dict[str, Any] = field(default_factory=dict)
    events: list[Event] = field(default_factory=list)
    dropped: list[str] = field(default_factory=list)  # malformed parts of result.json
    #: result.json as written, before its malformed parts were dropped: what the records
    #: database stores and a correction is compared with
    written: JsonObject = field(default_factory=dict)
    #: the kind's body as its analysis gave it, when it has just done so (`analysed`)
    body: ResultPart | None = None
    #: the kind's result model, decoded once (`model`), by its decoder
    _models: dict[Callable[[Sources], object], object] = field(default_factory=dict,
                                                               repr=False)

    @classmethod
    def load(cls, result: object, run_path: Path | None) -> Sources:
        frame, dropped = conform_result(result)
        src = cls(frame.doc, run_path, dropped=dropped, written=as_object(result) or {})
        src.frame = frame
        return src.beside_run()

    def beside_run(self) -> Sources:
        """With what the run directory adds (none without one)."""
        if self.run_path is None:
            return self
        self.meta = read_json_object(self.run_path / layout.META)
        # as the run read them: a placeholder left to fill in is no value to print
        self.stand_file = run_copy(self.run_path, layout.STAND)
        self.procedure_file = run_copy(self.run_path, layout.PROCEDURE)
        events = self.run_path / layout.EVENTS
        if events.exists():
            self.events = read_events(events)
        return self

    @classmethod
    def analysed(cls, result: KindResult[ResultPart], run_path: Path | None) -> Sources:
        """The run as its analysis has just given its result (result.json is its encoding,
        not read back): every section reads the frame the analysis gave (`KindResult.
        frame`, typed) and the kind's part its body, nothing decoded, when they hold what
        result.json holds (then nothing in them is malformed); else result.json's, as a
        reader of the file would."""
        if result.frame.body is None:
            src = cls.load(result.document, run_path)
        else:
            src = cls(result.document, run_path, written=result.document).beside_run()
            src.frame = result.frame
        src.body = result.body
        return src

    @property
    def walked(self) -> msgspec.Struct | JsonObject:
        """The result as a reader walks all of it (budgets wherever they sit, mains tones):
        the kind's own model when its analysis has just given it (`analysed`), else
        result.json (conformed)."""
        return self.frame.body if isinstance(self.frame.body, msgspec.Struct) else self.result

    @classmethod
    def read(cls, result_file: Path) -> Sources:
        """The run of `result_file` (a run directory's result.json, or one given beside
        it), decoded: ValueError when the file is not JSON, OSError when unreadable."""
        return cls.load(json.loads(result_file.read_text(encoding="utf-8")), result_file.parent)

    @classmethod
    def decode(cls, raw: bytes, run_path: Path | None) -> Sources:
        """The run of a result.json given as bytes (the file's, the register's copy):
        ValueError when they are not JSON."""
        return cls.load(json.loads(raw), run_path)

    def event_utc(self, kind: type[Event], last: bool = False) -> str | None:
        """When the event log first (or last) recorded an event of `kind`, as it wrote it."""
        found = (ev.last if last else ev.first)(self.events, kind)
        return found.utc or None if found is not None else None

    def model(self, decode: Callable[[Sources], M]) -> M:
        """The kind's result model (its codec's `decode` of `result`), decoded on first
        use and read by every section of the certificate and the DCC."""
        if decode not in self._models:
            self._models[decode] = decode(self)
        return cast(M, self._models[decode])

    @cached_property
    def equipment_in_force(self) -> dict[str, dict[str, str]]:
        """The calibration in force per stand key (its certificate, issuer and due date),
        as the register gave it at the run's start (meta.json's equipment_status,
        bench/app/register/gate.py); an entry lacking one of them is left out."""
        return {st.where: {"certificate": st.certificate, "issuer": st.issuer, "due": st.due}
                for st in self.start.equipment_status
                if st.where is not None and st.certificate is not None
                and st.issuer is not None and st.due is not None}

    @cached_property
    def start(self) -> StartMeta:
        """meta.json's account of the run's start (the performer, the equipment's status
        in the register), typed once for the certificate and the DCC."""
        return start_meta(self.meta)

    @cached_property
    def stand(self) -> StandIdentity:
        """The stand file's `stand` block, with what result.json says over it; a value
        that is no scalar (a malformed file's) reads as not stated."""
        block = self.stand_file.get("stand")
        said = {**(block if isinstance(block, dict) else {}),
                **{k: v for k, v in self.frame.stand.items() if v is not None}}
        return msgspec.convert({k: v for k, v in said.items()
                                if isinstance(v, str | int | float | bool)}, StandIdentity)

    @cached_property
    def frame(self) -> ResultFrame:
        """The run header, checks and verdict, typed (bench.report.result_frame): read
        once (`load` gives it as it conformed the result) and read by every section of
        the certificate and the DCC."""
        return ResultFrame.of(self.result)


#: a kind's check of its own part of result.json, in its codec (procedures/<kind>/codec.py):
#: the document with its malformed containers dropped, and their names
ResultConform = Callable[[JsonObject], tuple[JsonObject, list[str]]]


def conform_result(result: object) -> tuple[ResultFrame, list[str]]:
    """The result with malformed containers dropped, and the list of what was dropped:
    the kind's part by the kind's codec (its certificate part's `result_conform`,
    `ConformsResult`), the frame's here. A result that names no kind is read by every
    installed kind's."""
    from bench.core.registry import procedure_kind, procedure_names

    doc = as_object(result)
    if doc is None:
        return ResultFrame.conform(result)
    named = doc.get("procedure")
    dropped: list[str] = []
    for name in [str(named)] if named else procedure_names():
        try:
            part = getattr(procedure_kind(name), "certificate", None)
        except (KeyError, ImportError, AttributeError):
            continue    # a kind this installation lacks: its part is kept as written
        if isinstance(part, ConformsResult):
            doc, more = part.result_conform(doc)
            dropped += more
    frame, more = ResultFrame.conform(doc)
    return frame, dropped + more


@runtime_checkable
class ConformsResult(Protocol):
    """A kind's certificate part that names its codec's check of its part of result.json
    (a kind without one is read as written)."""

    result_conform: ResultConform


def read_json_object(path: Path) -> dict[str, Any]:
    """A JSON object from a run directory's file, or {} if it is missing or damaged."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def read_frame(result_file: Path) -> ResultFrame | None:
    """The frame of a result.json, read as written; None when it is missing, damaged or
    no object (a run not analysed yet, or whose analysis is being written)."""
    try:
        found = json.loads(result_file.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return ResultFrame.of(found) if isinstance(found, dict) else None


def beside(run_path: Path, run_id: str) -> ResultFrame | None:
    """The frame of the result.json of the run `run_id` beside `run_path` (the runs folder:
    an as-found run), read as written; None when it is missing, damaged or no object."""
    return read_frame(run_path.parent / run_id / layout.RESULT)
