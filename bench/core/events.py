"""The journal's events as typed records: one declaration per event kind, written and
read through it (issue 61; Bluesky's event-model is the anchor).

A writer builds the kind's record and hands it to `RunDir.write`; a reader gets the same
class back from `RunDir.typed_events()` (or `decode` for a mapping that came another way,
e.g. from the lab database) and tests it with `isinstance`. A field renamed or forgotten
on one side fails on both, and mypy follows each field from the step that writes it to
the page that shows it.

The line on disk is what it was before the records were typed (`utc`, `t_s`, `session`,
`event`, then the kind's fields in their declared order): runs written by earlier versions
read back the same, and an event kind a reader does not know (a newer bench's, a plug-in's
not loaded) comes back as `Unrecognised`, never dropped and never an error. A record of a
known kind whose field has the wrong type comes back as `Malformed`, naming the field;
readers skip both, the run's log shows them.

The kind-neutral events are declared here; a procedure kind declares its own beside its
steps (procedures/rate_ladder/events.py) as subclasses of `Event`.

msgspec, not pydantic (issue 60 asks which and why; measured on the demo, 29 Nov 2026):
decoding a journal line into its typed record 0.4 us against 2.3 us, the demo's
result.json (713 KB, its checks typed) 0.7 ms against 1.2 ms, import 24 ms against 73 ms
(the CLI's start-up), and a malformed field is named by its JSON path (`Expected `float`,
got `str` - at `$.checks[0].set_rate_dps``).
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Iterable, Iterator, Mapping
from typing import ClassVar, Protocol, TypeVar, runtime_checkable

import msgspec

from bench.core.kind_index import registered
from drivers.json_types import JsonObject, JsonValue

#: the keys every line starts with, set by the journal when it writes the record
FRAME = ("utc", "t_s", "session", "event")


class LiveRow(msgspec.Struct, frozen=True, kw_only=True):
    """A row of the station's table of results as they come, declared by the kind whose
    first look gives it (the ladder's `ResultRow`): the station passes it to the kind's
    `live_table` and encodes it for /api with `msgspec.to_builtins`, fields in order."""


class Event(msgspec.Struct, kw_only=True, frozen=True, tag_field="event"):
    """Common to every journal record. The journal sets the frame (`utc`, the stand
    clock's `t_s`, the session's number) as it writes; a record built by a step leaves
    them at their defaults."""

    #: a field whose mapping is spread into the line's own keys (the identity record's
    #: instruments, named by role): on reading, every key not declared goes back into it
    SPREAD: ClassVar[str] = ""
    #: the station's log of a run shows this event (its live page and the fleet's page of
    #: a bench): set by each kind on the records its operator follows, so the station
    #: names no kind's events (`station_log_kinds`)
    STATION_LOG: ClassVar[bool] = False

    utc: str = ""
    t_s: float | None = None
    session: int = 0

    @property
    def kind(self) -> str:
        return kind_of(type(self))

    def log_text(self) -> str | None:
        """What a run's log on the station says of this event, worded by the kind that
        declares it (None: the station's generic wording, the kind's name and reason)."""
        return None

    def live_rows(self) -> list[LiveRow]:
        """Rows this event adds to the station's table of results as they come (a kind's
        first look at its data; none for most events)."""
        return []


@runtime_checkable
class TimedHalf(Protocol):
    """A record of turns timed by the counter's zero mark (docs/method.md A1): what the
    station's per-turn panel and the records' check values read, whichever kind wrote it."""

    @property
    def axis(self) -> str: ...
    @property
    def unit(self) -> str: ...
    @property
    def session(self) -> int: ...
    @property
    def t_s(self) -> float | None: ...
    @property
    def set_rate_dps(self) -> float: ...
    @property
    def edges_s(self) -> list[float]: ...
    @property
    def fog_lost(self) -> int: ...


E = TypeVar("E", bound=Event)


def kind_of(cls: type[Event]) -> str:
    tag = cls.__struct_config__.tag
    return tag if isinstance(tag, str) else ""


_KINDS: dict[str, type[Event]] = {}
_PLUGINS_LOADED = False
_SCANNED = 0        # Event subclasses seen by the last scan


def _subclasses(cls: type[Event]) -> Iterator[type[Event]]:
    for sub in cls.__subclasses__():
        yield sub
        yield from _subclasses(sub)


def declared(kind: str) -> type[Event] | None:
    """The record class declared for an event kind (looked up again when a plug-in's
    events module was imported after the last lookup)."""
    cls = _KINDS.get(kind)
    if cls is None:
        _scan()
        cls = _KINDS.get(kind)
    return cls


def station_log_kinds() -> tuple[str, ...]:
    """The tags of every declared event the station's log shows (`Event.STATION_LOG`),
    the installed kinds' and a plug-in's among them: what the fleet asks its database
    for, read off the declarations."""
    _scan()
    return tuple(k for k, c in _KINDS.items() if c.STATION_LOG)


def _scan() -> None:
    """Load the kinds' declarations once, and rebuild the table of kinds when a class was
    declared since the last scan (a journal with many lines of an unknown kind counts the
    classes, not rebuilds the table, a line)."""
    global _PLUGINS_LOADED, _SCANNED
    if not _PLUGINS_LOADED:
        _PLUGINS_LOADED = True
        _load_kind_declarations()
    found = list(_subclasses(Event))
    if len(found) != _SCANNED:
        _SCANNED = len(found)
        # a class whose tag is its own name is a base, not a declared kind
        _KINDS.update({kind_of(c): c for c in found
                       if kind_of(c) and kind_of(c) != c.__name__})


def _load_kind_declarations() -> None:
    """Import each installed kind's `events` module (where a kind declares its journal
    records): a reader of any run's journal, the station's or the lab's, reads every
    kind's events as their records without naming the kinds."""
    modules = [value.partition(":")[0] for value in registered().values()]
    for module in modules:
        # the kind's package ("procedures.rate_ladder:KIND") or its module's package
        for package_name in dict.fromkeys((module, module.rpartition(".")[0])):
            try:
                if package_name and importlib.util.find_spec(f"{package_name}.events"):
                    importlib.import_module(f"{package_name}.events")
                    break
            except ImportError:
                continue    # no events module: the kind's lines stay as written


def encode(ev: Event) -> JsonObject:
    """The line's mapping: the frame first, then the kind's fields as declared (fields a
    kind omits at their default are left out, as its writer did before)."""
    body: JsonObject = msgspec.to_builtins(ev)
    for key in FRAME:
        body.pop(key, None)
    spread = type(ev).SPREAD
    if spread:
        inner = body.pop(spread, None) or {}
        body = {**body, **inner} if isinstance(inner, dict) else body
    return {"utc": ev.utc, "t_s": ev.t_s, "session": ev.session, "event": ev.kind, **body}


class Unrecognised(Event, tag="?", frozen=True):
    """A line whose kind no loaded declaration knows, kept as written."""

    name: str
    fields: JsonObject = {}


class Malformed(Event, tag="!", frozen=True):
    """A line of a known kind that does not read as its declaration (`problem` names the
    field), kept as written."""

    name: str
    problem: str
    fields: JsonObject = {}


def _frame(rec: Mapping[str, JsonValue]) -> dict[str, object]:
    utc, t_s, session = rec.get("utc"), rec.get("t_s"), rec.get("session")
    return {"utc": utc if isinstance(utc, str) else "",
            "t_s": t_s if isinstance(t_s, int | float) and not isinstance(t_s, bool) else None,
            "session": session if isinstance(session, int) and not isinstance(session, bool)
            else 0}


def name_of(rec: Mapping[str, JsonValue]) -> str:
    """The kind a line names, declared or not (for messages about raw lines)."""
    name = rec.get("event")
    return name if isinstance(name, str) else ""


def decode(rec: Mapping[str, JsonValue]) -> Event:
    """A journal line's record (already parsed from JSON) as its kind's declaration."""
    name = rec.get("event")
    cls = declared(name) if isinstance(name, str) else None
    if cls is None:
        return Unrecognised(name=str(name), fields=dict(rec), **_frame(rec))  # type: ignore[arg-type]
    data = dict(rec)
    if cls.SPREAD:
        names = set(cls.__struct_fields__) | set(FRAME)
        data[cls.SPREAD] = {k: data.pop(k) for k in list(data) if k not in names}
    try:
        return msgspec.convert(data, cls)
    except msgspec.ValidationError as e:
        return Malformed(name=str(name), problem=str(e), fields=dict(rec),
                         **_frame(rec))  # type: ignore[arg-type]


def plain(ev: Event) -> JsonObject:
    """The record as the JSON mapping it was written as (for the station's pages)."""
    if isinstance(ev, Unrecognised | Malformed):
        return dict(ev.fields)
    return encode(ev)


def decode_all(records: Iterable[Mapping[str, JsonValue]]) -> list[Event]:
    return [decode(r) for r in records]


def of_kind(events: Iterable[Event], cls: type[E]) -> list[E]:
    return [e for e in events if isinstance(e, cls)]


def first(events: Iterable[Event], cls: type[E]) -> E | None:
    return next((e for e in events if isinstance(e, cls)), None)


def last(events: Iterable[Event], cls: type[E]) -> E | None:
    found: E | None = None
    for e in events:
        if isinstance(e, cls):
            found = e
    return found


# -- the kind-neutral events, in the order a session writes them ------------------------

class SessionStarted(Event, tag="session_start", frozen=True):
    """A `bench run` or `--resume` began: who, how, with what."""

    STATION_LOG: ClassVar[bool] = True
    resume: bool = False
    sim: bool = False
    done_units: list[str] = []
    clock_speed: float | None = None
    argv: list[str] = []
    version: str = ""
    prompts: str = ""          # "--yes" or "operator"
    pid: int | None = None
    #: the authenticated performer (account, name, role), None when nobody logged in;
    #: an older run wrote the account as text
    performer: dict[str, str | None] | str | None = None
    os_user: str | None = None

    @property
    def performer_account(self) -> str | None:
        p = self.performer
        acc = p.get("account") if isinstance(p, dict) else p
        return acc if isinstance(acc, str) and acc else None


class CalibrationOverdue(Event, tag="calibration_overdue", frozen=True):
    where: str
    item: str
    certificate: str | None = None
    due: str | None = None


class RecordsOverdue(Event, tag="records_overdue", frozen=True):
    text: str


class OutOfControl(Event, tag="out_of_control", frozen=True):
    text: str


class Identity(Event, tag="identity", frozen=True):
    """Each instrument of an axis as it identified itself, by role (`counter`, `fog`,
    `drive`, `counter_reference`, a DMM's `x-dmm`...)."""

    SPREAD: ClassVar[str] = "instruments"
    axis: str
    instruments: dict[str, str] = {}


class IdentityMismatch(Event, tag="identity_mismatch", frozen=True):
    where: str
    stated: str
    reported: str
    query: str


class FogCapture(Event, tag="fog_capture", frozen=True):
    """A FOG opened while the clock runs: where its raw capture starts (drivers/fog.py
    `first_index`)."""

    axis: str
    first_index: int | None = None
    rate_hz: float | None = None


class Planned(Event, tag="plan", frozen=True):
    steps: int
    estimate_s: float
    step_estimates_s: list[float] = []


class Prompted(Event, tag="prompt", frozen=True):
    """An operator prompt, its answer, who gave it ("--yes" or "operator") and when."""

    STATION_LOG: ClassVar[bool] = True
    text: str
    answered: str
    answered_by: str = ""      # older logs say only answered: yes | operator
    answer: str = ""
    asked_utc: str = ""
    answered_utc: str = ""


class StepStarted(Event, tag="step_start", frozen=True):
    index: int
    action: str
    axis: str | None = None
    unit: str | None = None
    describe: str = ""


class StepDone(Event, tag="step_done", frozen=True):
    index: int
    action: str
    unit: str | None = None


class UnitDone(Event, tag="unit_done", frozen=True):
    unit: str


class Completed(Event, tag="completed", frozen=True):
    STATION_LOG: ClassVar[bool] = True
    wall_s: float | None = None


class Aborted(Event, tag="abort", omit_defaults=True, frozen=True):
    STATION_LOG: ClassVar[bool] = True
    reason: str = ""
    error: str = ""
    traceback: str | None = None


class SafeStopped(Event, tag="safe_stop", omit_defaults=True, frozen=True):
    STATION_LOG: ClassVar[bool] = True
    ok: bool
    error: str | None = None


class Refused(Event, tag="refused", frozen=True):
    STATION_LOG: ClassVar[bool] = True
    reason: str


class Exited(Event, tag="exit", frozen=True):
    STATION_LOG: ClassVar[bool] = True
    status: int
    cause: str | None = None
    later: list[str] = []


class LabLink(Event, tag="lab_link", frozen=True):
    state: str                 # "down" or "up"
    reason: str | None = None


class TornTail(Event, tag="torn_tail", frozen=True):
    file: str
    bytes: int
    note: str = ""


class SessionLost(Event, tag="session_lost", frozen=True):
    """Written by a later process for a session it found gone without an exit."""

    ended: str = ""            # "killed or crashed" (bench/core/journal.py KILLED)
    pid: int | None = None
    last_utc: str | None = None
    last_step: str | None = None
    found_by: str = ""
