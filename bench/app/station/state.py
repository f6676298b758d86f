"""A run's state as the station reads it from the run directory (bench/app/station/live.py)
and words it (view.py), typed: the page's wording reads attributes, and the state's JSON
(the live stream, /api) is these records encoded (bench/report/codec.py `encode`), in
their fields' order, as the hand-built mappings were before (issue 60).
"""

from __future__ import annotations

import msgspec

from bench.core.events import LiveRow

FOG_TAIL_S = 30.0                 # bench seconds of FOG record shown


class StepNow(msgspec.Struct, kw_only=True):
    """The step a session is at (its last `step_start`), and whether it is done."""

    index: int
    number: int                 # 1 = first
    action: str
    axis: str | None
    unit: str | None
    describe: str
    done: bool

    @property
    def words(self) -> str:
        """'axis action - describe', as the page names the step."""
        words = " ".join(x for x in (self.axis, self.action) if x)
        return f"{words} - {self.describe}" if self.describe else words


class Progress(msgspec.Struct, kw_only=True):
    """Step, progress and ETA of one session, in bench time and in wall time
    (live.py `progress_of`)."""

    steps: int
    steps_done: int
    step: StepNow | None
    fraction: float | None
    bench_time_s: float
    bench_left_s: float | None
    speed: float | None          # bench seconds per wall second, measured
    wall_left_s: float | None
    completed: bool              # the engine journaled `completed` (the plan is done)


class FogTrace(msgspec.Struct, kw_only=True):
    """The last seconds of a FOG capture, decoded and decimated (bench time, deg/s), and
    what the tail read showed (absent when there is no capture to read)."""

    t_s: list[float] = []
    rate_dps: list[float] = []
    tail_s: float | msgspec.UnsetType = msgspec.UNSET
    tail_crc_errors: int | msgspec.UnsetType = msgspec.UNSET
    tail_lost_frames: int | msgspec.UnsetType = msgspec.UNSET


class AxisHealth(msgspec.Struct, kw_only=True):
    """When each instrument of an axis was last heard (wall seconds ago and UTC), the FOG
    frames its timed halves lost, and for the axis running, its FOG tail's counts."""

    axis: str
    fog_lost_in_halves: int
    fog_age_s: float | None
    fog_utc: str | None
    drive_age_s: float | None
    drive_utc: str | None
    counter_age_s: float | None
    counter_utc: str | None
    fog_tail_s: float | None | msgspec.UnsetType = msgspec.UNSET
    fog_tail_crc_errors: int | None | msgspec.UnsetType = msgspec.UNSET
    fog_tail_lost_frames: int | None | msgspec.UnsetType = msgspec.UNSET

    def age_s(self, instrument: str) -> float | None:
        """Seconds since the instrument (fog, drive, counter) was last heard."""
        return {"fog": self.fog_age_s, "drive": self.drive_age_s,
                "counter": self.counter_age_s}[instrument]

    def utc(self, instrument: str) -> str | None:
        return {"fog": self.fog_utc, "drive": self.drive_utc,
                "counter": self.counter_utc}[instrument]


class Health(msgspec.Struct, kw_only=True):
    """The bench's health as its files show it (live.py `health`)."""

    axes: list[AxisHealth]
    last_update_s: float | None
    last_update_utc: str | None
    stale: bool
    stale_after_s: float
    warnings: list[str]


class PageState(msgspec.Struct, kw_only=True):
    """What a run's page words (view.py): its status and how it ended, the progress it
    reached, and for the station's own runs the first looks at its data."""

    status: str
    progress: Progress
    cause: str | None
    later: list[str]
    sessions: int
    session: int | None
    ended_utc: str | None
    ended: bool = False
    #: the rows the kinds' first looks add (`Event.live_rows`), as the kind words them
    results: list[LiveRow] = []
