"""Open a stand's instruments from its stand file: the same code for hardware and twins.

The drivers do not know whether they talk to a real drive, counter and FOG or to their
twins: the simulated bench only rewrites the stand's addresses (resource strings, the
serial port, the CAN channel) before this module opens them.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypeVar

from bench.core import rundir_layout as layout
from bench.core.config import StandAxis
from bench.core.events import Identity
from bench.core.journal import JsonLines, RunDir
from bench.core.journal_codec import encode_line
from bench.core.protocols import Counter as CounterLike
from bench.core.protocols import Drive
from bench.core.protocols import Fog as FogLike
from bench.core.stops import Resource, StopOutcome, Stops, attempt
from drivers.axis import Axis
from drivers.axis_link import RawSink
from drivers.clock import Clock
from drivers.counter import Counter, CounterError
from drivers.fog import Fog
from drivers.json_types import JsonLike, Readback

T = TypeVar("T")

#: seconds of FOG samples the live driver keeps: the run's memory must not grow with its
#: length; the analysis reads every sample from the raw capture (drivers.fog.CaptureCursor)
LIVE_FOG_KEEP_S = 60.0


@dataclass
class AxisInstruments:
    """One table axis: its drive, and the counter and FOG that watch it."""

    name: str
    drive: Drive
    counter: CounterLike | None = None
    fog: FogLike | None = None
    identities: dict[str, str] = field(default_factory=dict)
    logs: dict[str, JsonLines] = field(default_factory=dict)
    reference_text: str | None = None  # the counter's timebase as read back (journal)
    refusal: Exception | None = None   # a stand claim the instruments denied at opening
    #: the FOG is opened only for this axis's own steps (open_axis fog_when_used)
    fog_later: bool = False

    @property
    def fog_waiting(self) -> bool:
        """The FOG is made and not opened yet (opening places its first index)."""
        return self.fog is not None and self.fog.first_index is None


#: how `Bench.abandon` notes a stop's failure on the error that ended the opening
STOPPING_NOTE = "also, while stopping: "


class Bench:
    """All instruments of a run; `safe_stop` ramps every axis to zero and disables it.

    Each instrument and raw log registers its close on the bench's stop registry as it is
    opened (bench/core/stops.py), which is itself registered with the command's registry
    (a session's, `bench devices`') as the bench is made: closed last opened first, each
    whatever the others do, every outcome typed. Closing twice is harmless.
    """

    def __init__(self) -> None:
        self.axes: dict[str, AxisInstruments] = {}
        self.stops = Stops.child("the instruments", "instrument")

    def enter(self, cm: AbstractContextManager[T], resource: Resource = "instrument") -> T:
        obj = cm.__enter__()
        name = getattr(obj, "name", None) or getattr(obj, "port", None) or type(obj).__name__
        self.stops.add(str(name), lambda: cm.__exit__(None, None, None), resource)
        return obj

    def callback(self, fn: Callable[[], None], name: str,
                 resource: Resource = "instrument") -> None:
        self.stops.add(name, fn, resource)

    def log(self, path: Path) -> JsonLines:
        j = JsonLines(path)
        self.stops.add(f"raw log {j.path}", j.close, "log")
        return j

    def safe_stop(self, log: Callable[[str], None]) -> tuple[StopOutcome, ...]:
        """Every axis through the drive's one stop sequence (drivers/axis.py safe_stop),
        the axes left open; one outcome per axis."""
        return tuple(attempt(f"safe stop: {ax.name}", _stopping(ax.drive, log), "axis")
                     for ax in self.axes.values())

    def rest(self, axis: str) -> None:
        """A plan's last step on `axis`: ramp to zero, wait for standstill, disable. Raises
        what fails: a step's failure aborts the run, and the engine's safe stop follows."""
        drive = self.axes[axis].drive
        drive.stop()
        drive.disable()

    def abandon(self, error: BaseException) -> None:
        """Opening failed with `error`: stop what was opened and close all. `error` stays
        the one reported; the outcomes reach the command's registry (and, for a reader
        of the traceback, are noted on `error`)."""
        for outcome in self.stop_and_close(lambda s: None):
            if not outcome.ok:
                error.add_note(f"{STOPPING_NOTE}{outcome.text}")

    def close(self) -> tuple[StopOutcome, ...]:
        """Close every instrument and raw log (last opened first), each whatever the others
        do; their outcomes, raises none."""
        return self.stops.run()

    def stop_and_close(self, log: Callable[[str], None]) -> tuple[StopOutcome, ...]:
        """After a failure: safe stop, then close. The outcomes, raises none: the first
        cause stays what the operator reads, these go beneath it."""
        self.stops.record(*self.safe_stop(log))
        return self.close()


def _stopping(drive: Drive, log: Callable[[str], None]) -> Callable[[], None]:
    """The drive's safe stop as a stop that raises what it could not do."""
    def stop() -> None:
        errors = drive.safe_stop(log)
        if errors:
            raise RuntimeError("; ".join(errors))
    return stop


def with_readback(identity: str, readback: Readback, manual: str | None = None
                  ) -> str:
    """An instrument's identity with the settings it read back at connect (and the manual
    its driver follows): one string, so the run's `identity` event, `bench devices` and
    the certificate's instrument table all carry them."""
    out = identity
    if readback:
        out += "; read back: " + ", ".join(f"{k} = {v}" for k, v in readback.items())
    if manual:
        out += f"; driver checked against: {manual}"
    return out


def identity_record(ax: AxisInstruments) -> Identity:
    """The `identity` event of one axis: each instrument's identity with its read-back,
    and the counter's reference as read back."""
    return Identity(axis=ax.name, instruments={
        **ax.identities,
        **({"counter_reference": ax.reference_text} if ax.reference_text else {})})


def manual_note(manual: str) -> str:
    """What `bench devices` and the certificate say of a driver profile's source: the
    manual it was checked against, or UNVERIFIED where no manual was found."""
    if manual.strip().lower().startswith("unverified"):
        return "UNVERIFIED (no manual found)"
    return manual.split(":")[0]


class StandClaimError(Exception):
    """The stand file claims what the instrument, asked, denies: the input is invalid."""


def check_references(bench: Bench) -> None:
    """Refuse a run whose stand claims a counter reference the counter denied when it was
    opened (Counter.verify_reference: the traceability of the second rests on it, and the
    stand's timebase limit assumes it). Called once the bench can stop safely, before
    anything moves."""
    for ax in bench.axes.values():
        if ax.refusal is not None:
            raise ax.refusal


def raw_text_logger(log: JsonLines, clock: Clock) -> Callable[[str, bytes], None]:
    """A raw-exchange sink for SCPI drivers: every byte, as text, with the bench time."""
    def raw(direction: str, data: bytes) -> None:
        log.write(encode_line({"t_s": clock.now(), "dir": direction,
                               "data": data.decode("latin-1")}))
    return raw


def _raw_record_logger(log: JsonLines, clock: Clock) -> RawSink:
    """A sink for the drive's readings and commands (called from the CAN thread)."""
    def raw(kind: str, record: dict[str, JsonLike]) -> None:
        log.write(encode_line({"t_s": clock.now(), "kind": kind, **record}))
    return raw


def open_axis(bench: Bench, spec: StandAxis, clock: Clock, run: RunDir | None, *,
              counter: bool = True, fog: bool = True,
              fog_when_used: bool = False) -> AxisInstruments:
    """Open one axis's instruments (drive first, so a failure later still stops it).

    `fog_when_used`: the FOG is made (its declared identity known) but opened only by
    `fog_for_axis`, for the axis's own steps; a FOG streaming while another axis is
    measured is recorded for nothing (on the paper ladder it cost ~40 s of 130).

    The drive's controller node id was settled when the stand was parsed: the axes
    sharing a CAN bus decide it together (bench/core/canbus.py)."""
    name, d = spec.name, spec.drive
    drive_log = bench.log(run.raw_path(layout.drive_log(name))) if run else None
    drive = Axis(name, d, clock=clock,
                 raw=_raw_record_logger(drive_log, clock) if drive_log else None)
    bench.enter(drive, "axis")
    ax = AxisInstruments(name, drive)
    if drive_log:
        ax.logs["drive"] = drive_log
    bench.axes[name] = ax
    ax.identities["drive"] = with_readback(drive.identity(), drive.readback)
    c = spec.counter
    if counter and c:
        clog = bench.log(run.raw_path(layout.counter_log(name))) if run else None
        cnt = Counter.from_settings(c, clock,
                                    raw=raw_text_logger(clog, clock) if clog else None)
        bench.enter(cnt)
        if clog:
            ax.logs["counter"] = clog
        cnt.configure(**c.input_settings())
        try:
            cnt.verify_reference(c.reference, c.timebase_limit_rel)
        except CounterError as e:
            # refused by check_references once the bench can stop safely, before any move
            ax.refusal = StandClaimError(f"axes.{name}.counter.reference: {e}")
        got = str(cnt.readback.get("counter.reference", "")).upper()
        checked = ("signal checked with SENS:ROSC:EXT:CHEC ONCE"
                   if cnt.profile.has_reference_check else
                   "this model has no check command: its error queue is read after")
        ax.reference_text = (
            f"external reference at Ext Ref In (SENS:ROSC:SOUR? EXT, {checked})"
            if got.startswith("EXT") else
            "internal oscillator (SENS:ROSC:SOUR? INT)" if got.startswith("INT") else
            "not confirmed: the counter refused the stand's reference (see the run's "
            "refusal)" if ax.refusal else "not reported by this model")
        ax.counter = cnt
        ax.identities["counter"] = with_readback(
            cnt.identify(), {**cnt.readback, "time tie": cnt.time_tie.source},
            manual_note(cnt.profile.manual))
    f = spec.fog
    if fog and f:
        fg = Fog.from_settings(f, raw_path=run.raw_path(layout.fog_capture(name)) if run else None,
                               clock=clock,
                               keep_samples=int(LIVE_FOG_KEEP_S * f.rate_hz) if run else None)
        ax.fog = fg
        ax.identities["fog"] = fg.identity()
        ax.fog_later = fog_when_used
        if not fog_when_used:
            _open_fog(bench, ax, run)
    return ax


def _open_fog(bench: Bench, ax: AxisInstruments, run: RunDir | None) -> Fog:
    fg = ax.fog
    assert isinstance(fg, Fog) and ax.fog_waiting
    if run is not None:   # runs after the FOG has closed (the stack is last-in-first-out)
        bench.callback(lambda: run.remember_digest(fg.raw_path, fg.raw_digest),
                       f"{fg.port} digest")
    fg.open()
    bench.callback(fg.close, fg.port)
    ax.identities["fog"] = with_readback(fg.identity(), fg.readback)
    return fg


def fog_for_axis(bench: Bench, axis: str, run: RunDir | None, *, opening: bool = True
                 ) -> Fog | None:
    """Before a step on `axis`: every other axis's FOG opened for its steps is closed
    (its units are done: the plan measures one axis after another), and, if `opening`,
    this axis's FOG is opened if it waits (open_axis fog_when_used). Returns the FOG
    opened now (its capture starts at `first_index`, drivers/fog.py), else None."""
    for other in bench.axes.values():
        if other.name != axis and other.fog_later and isinstance(other.fog, Fog) \
                and other.fog.is_open:
            other.fog.close()
    ax = bench.axes[axis]
    if ax.fog_later and isinstance(ax.fog, Fog) and not ax.fog_waiting \
            and not ax.fog.is_open:
        raise RuntimeError(f"{axis}: a step on this axis after its FOG was closed for the "
                           "next axis (the plan must measure one axis after another)")
    if opening and ax.fog is not None and ax.fog_waiting:
        return _open_fog(bench, ax, run)
    return None
