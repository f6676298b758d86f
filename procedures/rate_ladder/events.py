"""The rate ladder's journal records between its steps and its analysis.

A step writes one of these when its data are complete in the raw files; the analysis
(and a --resume deciding what to keep) reads the same class back, so a field renamed or
forgotten on one side fails on both (issue 12). The journal adds `utc`, `t_s` and
`session`; unknown keys in an older run's events are ignored.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypeVar

from bench.core.journal import RunDir
from drivers.fog import FogCheckpoint

E = TypeVar("E", bound="LadderEvent")


@dataclass(frozen=True)
class LadderEvent:
    """Common to the ladder's records: where they belong and how they are (de)coded."""

    KIND: ClassVar[str] = ""
    axis: str
    unit: str
    session: int = field(default=0, kw_only=True)   # set by the journal when written

    def write(self, run: RunDir) -> None:
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
                  if f.name != "session"}
        run.event(self.KIND, **fields)

    @classmethod
    def of(cls: type[E], e: dict[str, Any]) -> E:
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in e.items() if k in names})

    @classmethod
    def all_in(cls: type[E], events: list[dict[str, Any]]) -> list[E]:
        return [cls.of(e) for e in events if e.get("event") == cls.KIND]


@dataclass(frozen=True)
class StaticRecorded(LadderEvent):
    """The FOG at rest for the noise floor (docs/method.md A5): samples fog_from..fog_to."""

    KIND: ClassVar[str] = "static"
    fog_from: int
    fog_to: int
    rate_hz: float
    lost: int = 0
    fog_capture: FogCheckpoint | None = None   # decoder checkpoint before fog_from


@dataclass(frozen=True)
class HalfAcquired(LadderEvent):
    """One half of a +/- pair, complete: N turns timed by the counter (N + 1 zero-mark
    edges) and the FOG samples fog_from..fog_to that bracket them (docs/method.md A1-A3).
    Written last, so a --resume keeps every half that has one (docs/resume.md)."""

    KIND: ClassVar[str] = "acquire"
    half: int
    set_rate_dps: float
    turns: int
    edges_s: list[float]
    counter_records: list[int]         # the half's lines in the counter's raw log
    fog_from: int
    fog_to: int
    rate_hz: float
    counter_t0_s: float = 0.0          # the counter's start on the FOG's time axis
    counter_t0_u_s: float | None = None
    counter_readback: dict[str, str] = field(default_factory=dict)
    fog_lost: int = 0
    fog_capture: FogCheckpoint | None = None
    # how counter_t0_s was placed on the FOG's time axis (drivers/time_tie.py): the tie's
    # source, sync period, latency and its u, the sync pulse that started the counter,
    # when it was armed, and the FOG's sample index convention (index n at n / rate_hz
    # from the session's stand-clock zero): all a later analysis needs to re-place the
    # half after a restart, each session on its own axis (docs/resume.md)
    time_tie: dict[str, str | float | None] = field(default_factory=dict)

    @property
    def sign(self) -> int:
        return 1 if self.set_rate_dps > 0 else -1

