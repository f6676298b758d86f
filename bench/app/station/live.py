"""What a running (or finished) bench is doing, read from its run directory alone.

The station view never talks to the bench process. The bench already journals every step
(events.jsonl, fsynced per line) and streams every raw byte to raw/s<session>/; reading
those files shows the run without sitting in its acquisition path, so a view that dies,
hangs or is slow costs the run nothing, and a page reload or a server restart loses
nothing either (the files are the state).

Everything here is read-only and tolerant: a torn last line, a raw file not yet created,
a run of an older version without the newer event fields: each gives less detail, never
an error.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import NotRequired, TypedDict, TypeVar

import msgspec
import numpy as np

from bench.app.names import resume_command
from bench.app.records.extract import kind_name
from bench.app.station.state import (
    FOG_TAIL_S,
    AxisHealth,
    FogTrace,
    Health,
    PageState,
    Progress,
    StepNow,
)
from bench.app.station.view import page_view, station_of
from bench.core import events as ev
from bench.core import rundir_layout as layout
from bench.core.config import FogSettings
from bench.core.events import Event, LiveRow, TimedHalf
from bench.core.journal import fog_capture_starts
from bench.core.journal_codec import (
    DriveFeedback,
    read_verdict,
    tail_events,
    tail_records,
)
from bench.core.yamlfile import read_mapping
from bench.report.certificate.sources import read_frame
from bench.report.codec import encode
from bench.report.result_frame import ResultFrame
from drivers.fog import dps_per_unit
from drivers.fog_formats import AXES, DecodeState, decode, get_format
from drivers.json_types import JsonLike, JsonValue

T = TypeVar("T")

FULL_TURN_DEG = 360.0             # one zero mark per turn (docs/method.md A1)
TRACE_POINTS = 600                # a plot of a half never needs more points than pixels
DRIVE_TAIL_BYTES = 96 * 1024      # about 600 feedback readings


def read_events(run_path: Path) -> list[Event]:
    """Every event of the run (all sessions), each as its kind's record; a torn last line
    is skipped."""
    return tail_events(run_path / layout.EVENTS, 1 << 62)


def pid_alive(pid: int | None) -> bool:
    """A process of this machine lives under `pid` (bench/app/fleet/lost.py)."""
    from bench.app.fleet.lost import pid_exists

    return pid is not None and pid > 0 and pid_exists(pid)


def decimate(t: np.ndarray, y: np.ndarray, points: int = TRACE_POINTS
             ) -> tuple[list[float], list[float]]:
    """Block means (not every k-th sample, which would alias the FOG's noise)."""
    n = len(y)
    if n == 0:
        return [], []
    k = max(1, math.ceil(n / points))
    m = n // k * k
    if m == 0:
        return [float(t.mean())], [float(y.mean())]
    tb = t[:m].reshape(-1, k).mean(axis=1)
    yb = y[:m].reshape(-1, k).mean(axis=1)
    return [round(float(v), 4) for v in tb], [float(v) for v in yb]


def fog_trace(raw: Path, fog: FogSettings, tail_s: float = FOG_TAIL_S,
              first_index: int = 0) -> FogTrace:
    """The last `tail_s` of a FOG capture, decoded and decimated (bench time, deg/s).

    Time is the frame's position in the capture over the output rate, from the
    capture's `first_index` (its `fog_capture` event: the ladder opens an axis's FOG
    for its own steps): exact while no bytes were lost, a few frames off after a
    corrupt stretch, which a live plot can bear.
    """
    try:
        f = get_format(fog.format)
        size = raw.stat().st_size
    except (FileNotFoundError, ValueError, KeyError):
        return FogTrace()
    want = int(tail_s * fog.rate_hz) * f.size
    start = max(0, size - want)
    with open(raw, "rb") as fh:
        fh.seek(start)
        buf = fh.read(size - start)
    frames, _, stats = decode(buf, f, DecodeState(offset=start))
    seen = FogTrace(tail_s=tail_s, tail_crc_errors=int(stats.crc_errors),
                    tail_lost_frames=int(stats.lost_frames))
    if not len(frames) or fog.axis not in AXES:
        return seen
    scale = dps_per_unit(fog.units, fog.rate_hz)
    t = (first_index + frames.offset.astype(np.float64) / f.size) / fog.rate_hz
    y = frames.rates[:, AXES.index(fog.axis)].astype(np.float64) * scale
    ts, ys = decimate(t, y)
    return msgspec.structs.replace(seen, t_s=ts, rate_dps=ys)


def drive_trace(raw: Path) -> dict[str, list[float]]:
    """The drive's recent velocity feedback (TPDO), for the settling plot."""
    readings = [(rec.t_s, rec.velocity_dps)
                for rec in tail_records(raw, DRIVE_TAIL_BYTES, DriveFeedback)
                if rec.kind == "feedback" and rec.t_s is not None
                and rec.velocity_dps is not None]
    return {"t_s": [float(t) for t, _ in readings],
            "velocity_dps": [float(v) for _, v in readings]}


def turn_rates(acquire: TimedHalf) -> dict[str, JsonLike]:
    """Per-turn rates of one timed half from its zero-mark edges (docs/method.md A1: w = 360/T,
    signed as commanded) and their deviation from the set rate (eq. 1, per turn)."""
    edges = np.asarray(acquire.edges_s, dtype=np.float64)
    set_dps = float(acquire.set_rate_dps)
    if edges.size < 2 or set_dps == 0:
        return {"set_rate_dps": set_dps, "rate_dps": [], "deviation_ppm": []}
    rate_dps = math.copysign(1.0, set_dps) * FULL_TURN_DEG / np.diff(edges)
    dev_ppm = (rate_dps - set_dps) / set_dps * 1e6
    return {"set_rate_dps": set_dps, "axis": acquire.axis, "unit": acquire.unit,
            "rate_dps": [float(v) for v in rate_dps],
            "deviation_ppm": [float(v) for v in dev_ppm]}


def _utc_s(stamp: str) -> float:
    return datetime.fromisoformat(stamp).timestamp()


def progress_of(session: list[Event]) -> Progress:
    """Step, progress and ETA of one session, in bench time and in wall time.

    The wall ETA is the bench time left over the speed measured so far in this session
    (bench seconds per wall second between its first and latest event), never the clock
    speed configured: a loaded machine or a twin-paced clock changes the speed.
    """
    plan = ev.last(session, ev.Planned)
    steps = plan.steps if plan else 0
    estimates = [float(x) for x in plan.step_estimates_s] if plan else []
    total_s = float(plan.estimate_s) if plan else 0.0
    done = {e.index for e in ev.of_kind(session, ev.StepDone)}
    cur = ev.last(session, ev.StepStarted)
    timed = [(e.t_s, e.utc) for e in session if e.t_s is not None and e.utc]
    now_bench = float(timed[-1][0]) if timed else 0.0
    speed = None
    if len(timed) >= 2:
        dt_wall = _utc_s(timed[-1][1]) - _utc_s(timed[0][1])
        dt_bench = float(timed[-1][0]) - float(timed[0][0])
        if dt_wall > 0 and dt_bench > 0:
            speed = dt_bench / dt_wall
    left_s = None
    index = cur.index if cur is not None else None
    if cur is not None and index is not None and estimates and len(estimates) == steps:
        i = index
        left_s = sum(estimates[i:]) if i not in done else sum(estimates[i + 1:])
        started_s = cur.t_s
        if i not in done and started_s is not None:
            left_s -= min(estimates[i], max(0.0, now_bench - float(started_s)))
    elif total_s and cur is not None:
        left_s = total_s * (1 - len(done) / max(steps, 1))
    fraction = None
    if steps:
        fraction = len(done) / steps
        if left_s is not None and total_s > 0 and len(done) < steps:
            fraction = min(1.0, max(0.0, 1 - left_s / total_s))
    return Progress(
        steps=steps, steps_done=len(done),
        step=None if cur is None else StepNow(
            index=cur.index, number=(index or 0) + 1, action=cur.action, axis=cur.axis,
            unit=cur.unit, describe=cur.describe, done=cur.index in done),
        fraction=fraction, bench_time_s=now_bench, bench_left_s=left_s, speed=speed,
        wall_left_s=(left_s / speed) if (left_s is not None and speed) else None,
        completed=any(isinstance(e, ev.Completed) for e in session))


#: wall seconds without new data after which a running bench is flagged on the page: the
#: FOG streams hundreds of frames a second and the drive its feedback every few tens of ms,
#: so a second or two of silence is already a fault (a hung bench otherwise looks normal)
FOG_SILENT_S = 2.0
DRIVE_SILENT_S = 2.0
#: the page's "last update" turns into a stale warning after this long
STALE_S = 5.0


def _age_s(path: Path, now: float) -> float | None:
    """Wall seconds since `path` was last written, or None if it does not exist."""
    try:
        return max(0.0, now - path.stat().st_mtime)
    except OSError:
        return None


def _utc_of(age_s: float | None, now: float) -> str | None:
    """The wall time (UTC, ISO) of a last write `age_s` before `now`: a finished run's page
    says when each instrument was last heard, not how long ago, which grows forever."""
    if age_s is None:
        return None
    return datetime.fromtimestamp(now - age_s, UTC).isoformat(timespec="seconds")


def health(run_path: Path, raw: Path | None, axes: list[str], running: bool,
           fog_tail: FogTrace, axis: str | None,
           acquires: Sequence[TimedHalf], now: float | None = None) -> Health:
    """The bench's health as its files show it: when each instrument was last heard, the
    FOG's lost and broken frames, and how long since anything was written.

    Ages are wall time from the files' modification times (the bench writes every frame
    and reading as it arrives); warnings only while the run is running: a finished run's
    files are quiet by design.
    """
    now = time.time() if now is None else now
    per_axis: list[AxisHealth] = []
    warnings: list[str] = []
    ages = [a for a in [_age_s(run_path / layout.EVENTS, now)] if a is not None]
    for name in axes:
        lost = sum(e.fog_lost for e in acquires if e.axis == name)
        heard: dict[str, float | None] = {}
        for inst, suffix in (("fog", "fog.bin"), ("drive", "drive.jsonl"),
                             ("counter", "counter.jsonl")):
            age = _age_s(raw / f"{name}-{suffix}", now) if raw is not None else None
            heard[inst] = age
            if age is not None:
                ages.append(age)
        row = AxisHealth(axis=name, fog_lost_in_halves=lost,
                         fog_age_s=heard["fog"], fog_utc=_utc_of(heard["fog"], now),
                         drive_age_s=heard["drive"], drive_utc=_utc_of(heard["drive"], now),
                         counter_age_s=heard["counter"],
                         counter_utc=_utc_of(heard["counter"], now))
        if name == axis:
            crc_errors, lost_frames = (_or_none(fog_tail.tail_crc_errors),
                                       _or_none(fog_tail.tail_lost_frames))
            row = msgspec.structs.replace(row, fog_tail_s=_or_none(fog_tail.tail_s),
                                          fog_tail_crc_errors=crc_errors,
                                          fog_tail_lost_frames=lost_frames)
            if running:
                fog_age, drive_age = heard["fog"], heard["drive"]
                if fog_age is not None and fog_age > FOG_SILENT_S:
                    warnings.append(f"FOG {name}: no data for {fog_age:.0f} s")
                if drive_age is not None and drive_age > DRIVE_SILENT_S:
                    warnings.append(f"drive {name}: not heard for {drive_age:.0f} s "
                                    "(heartbeat/feedback)")
                if crc_errors:
                    warnings.append(f"FOG {name}: {crc_errors} CRC errors in "
                                    f"the last {FOG_TAIL_S:g} s")
                if lost_frames:
                    warnings.append(f"FOG {name}: {lost_frames} frames lost "
                                    f"in the last {FOG_TAIL_S:g} s")
        per_axis.append(row)
    last = min(ages) if ages else None
    stale = running and last is not None and last > STALE_S
    if stale:
        warnings.insert(0, f"no update for {last:.0f} s: the bench may be hung")
    return Health(axes=per_axis, last_update_s=last, last_update_utc=_utc_of(last, now),
                  stale=stale, stale_after_s=STALE_S, warnings=warnings)


def _or_none(value: T | msgspec.UnsetType) -> T | None:
    """A FOG tail's count, None when the tail was not read (no capture yet)."""
    return None if isinstance(value, msgspec.UnsetType) else value


def pair_rows(events: list[Event]) -> list[LiveRow]:
    """The results as they come: the rows each kind's first looks add (`Event.live_rows`;
    the ladder's: per axis, rate and direction, k and w0, delta +/- U, sigma, verdict)."""
    return [row for e in events for row in e.live_rows()]


def final_rows(frame: ResultFrame, run_path: Path | None = None) -> list[LiveRow]:
    """The final rows from result.json, as its kind's station part gives them (the
    ladder's: per axis and rate the figures the certificate prints with the pair's k and
    w0); none for a kind that gives none."""
    return station_of(frame.procedure or kind_name(frame, run_path)).result_rows(frame)


#: a session's exit status (bench/app/session.py EXIT_*, CONTRACT section 1) as the page
#: names how it ended; 3 without a cause is refined by `ending` (incomplete)
ENDINGS = {0: "passed", 1: "failed", 2: "refused", 3: "aborted"}
#: the statuses of a run that has ended (the page shows its end state, not a live view)
ENDED = ("passed", "failed", "refused", "aborted", "incomplete", "ended")


class Ending(TypedDict):
    """How a session ended (`ending`)."""

    status: str
    cause: str | None
    later: list[str]
    exit_status: int
    utc: str


class RunStatus(TypedDict):
    """A run's status from its last session (`run_status`)."""

    status: str
    cause: str | None
    later: list[str]
    session: int | None
    events: list[Event]
    pid: int | None
    exit_status: NotRequired[int]
    utc: NotRequired[str]


def ending(session: list[Event], run_path: Path) -> Ending | None:
    """How the session ended and its first cause, as the operator at the bench read it
    (bench/app/session.py: the exit event's cause; a refusal's own event; what failed
    later, while stopping, beneath it); None while the session has no exit event.

    Exit status 3 without a cause is a run that stopped short of a signed certificate with
    nothing having gone wrong at the bench: the outputs say which (no result.json, a run
    the analysis found incomplete, or no certificate), and `bench analyze` or `--resume`
    is what continues it, so the page names it incomplete, not aborted.
    """
    exit_ev = ev.last(session, ev.Exited)
    if exit_ev is None:
        return None
    code = exit_ev.status
    status = ENDINGS.get(code, "ended")
    cause = exit_ev.cause or None
    if status == "refused":
        refusal = ev.first(session, ev.Refused)
        cause = (refusal.reason if refusal else None) or cause \
            or "the input was refused (exit status 2)"
    elif status == "aborted" and not cause:
        status = "incomplete"
        verdict = read_verdict(run_path / layout.RESULT)
        if verdict is None:
            cause = (f"no result.json was written; `bench analyze {run_path}` writes it from "
                     "the raw data")
        elif verdict == "incomplete":
            cause = (f"not every step was measured (result.json: verdict incomplete); "
                     f"`{_resume(session, run_path)}` continues")
        else:
            cause = (f"measured (result.json: verdict {verdict}), but no certificate was "
                     f"written; `bench analyze {run_path}` writes it")
    elif status == "ended":
        cause = cause or f"exit status {code}"
    return {"status": status, "cause": str(cause) if cause else None,
            "later": list(exit_ev.later), "exit_status": code, "utc": exit_ev.utc}


def _resume(session: list[Event], run_path: Path) -> str:
    """The resume command as it works for this run: with --yes when its session ran so."""
    start = ev.first(session, ev.SessionStarted)
    return resume_command(run_path, start is not None and start.prompts == "--yes")


def run_status(events: list[Event], run_path: Path) -> RunStatus:
    """The run's status from its last session, one rule for the runs list and the run's
    page: how it ended (`ending`), else running while the bench process journaled at the
    session's start lives, else stopped (the process went without an exit: killed or
    crashed), or created when no session has started yet."""
    start = ev.last(events, ev.SessionStarted)
    if start is None:
        return {"status": "created", "cause": None, "later": [], "session": None,
                "events": [], "pid": None}
    session_no = start.session
    session = [e for e in events if e.session == session_no]
    pid = start.pid
    end = ending(session, run_path)
    if end is not None:
        return {**end, "session": session_no, "events": session, "pid": pid}
    if pid is not None and not pid_alive(pid):
        return {"status": "stopped", "later": [],
                "cause": ("the bench process is gone without journaling an exit (killed or "
                          f"crashed); `{_resume(session, run_path)}` continues"),
                "session": session_no, "events": session, "pid": pid}
    return {"status": "running", "cause": None, "later": [], "session": session_no,
            "events": session, "pid": pid}


def live_state(run_path: Path) -> dict[str, JsonLike]:
    """The station's view of one run directory (JSON-ready), with `view`: the same state
    worded and rounded for the page (bench/app/station/view.py)."""
    run_path = Path(run_path)
    events = read_events(run_path)
    starts = ev.of_kind(events, ev.SessionStarted)
    st = run_status(events, run_path)
    session_no, session, pid, status = st["session"], st["events"], st["pid"], st["status"]
    stand = read_mapping(run_path / layout.STAND)
    prog = progress_of(session)
    axis = prog.step.axis if prog.step is not None else None
    raw = layout.raw_dir(run_path, session_no) if session_no else None
    fog = FogTrace()
    drive: dict[str, list[float]] = {"t_s": [], "velocity_dps": []}
    if raw is not None and axis:
        settings = FogSettings.of_axis(stand, axis) if isinstance(stand, dict) else None
        if settings is not None:
            first = fog_capture_starts(session).get((int(session_no or 0), axis), 0)
            fog = fog_trace(raw / layout.fog_capture(axis), settings, first_index=first)
        drive = drive_trace(raw / layout.drive_log(axis))
    acquires = [e for e in events if isinstance(e, TimedHalf)]
    # the per-turn panel shows the axis now running, never the previous axis's last half
    shown_acquires = [e for e in acquires if not axis or e.axis == axis]
    result: JsonValue = None
    final: list[LiveRow] = []
    # result.json's frame as the page shows it (None: not written yet, or not JSON)
    frame = read_frame(run_path / layout.RESULT) if status != "running" else None
    if frame is not None:
        result = frame.doc.get("verdict")
        final = final_rows(frame, run_path)
    axes_now = [str(a) for a in ((stand.get("axes") or {}) if isinstance(stand, dict)
                                 else {})]
    used = [a for a in axes_now if any(getattr(e, "axis", None) == a for e in session)] \
        or axes_now
    # the events each kind declares for the station's log (Event.STATION_LOG)
    shown_events = [e for e in events if e.STATION_LOG][-40:]
    shown = [{k: v for k, v in ev.plain(e).items() if k not in ("traceback",)}
             for e in shown_events]
    ident = (stand.get("stand") or {}) if isinstance(stand, dict) else {}
    healthy = health(run_path, raw, used, status == "running", fog, axis, acquires)
    results = pair_rows(events)
    state: dict[str, JsonLike] = {
        "run": run_path.name,
        "title": _title(run_path),
        "stand": {k: ident.get(k) for k in ("maker", "model", "serial")},
        "simulated": isinstance(stand, dict) and "sim" in stand,
        "status": status,
        "ended": status in ENDED,
        "cause": st["cause"],
        "later": st["later"],
        "ended_utc": st.get("utc"),
        "session": session_no,
        "sessions": len(starts),
        "pid": pid,
        "progress": encode(prog),
        "turns": turn_rates(shown_acquires[-1]) if shown_acquires else None,
        "fog": {"axis": axis, **encode(fog)},
        "health": encode(healthy),
        "results": [encode(r) for r in results],
        "final": [encode(r) for r in final],
        "drive": {"axis": axis, **drive},
        "faults": [line for e, line in zip(shown_events, shown, strict=True)
                   if isinstance(e, ev.Aborted)
                   or (isinstance(e, ev.SafeStopped) and not e.ok)],
        "prompts": [line for e, line in zip(shown_events, shown, strict=True)
                    if isinstance(e, ev.Prompted)],
        "log": shown,
        "verdict": result,
        "files": [n for n in DOWNLOADS if (run_path / n).exists()],
    }
    page = PageState(status=status, progress=prog, cause=st["cause"], later=st["later"],
                     sessions=len(starts), session=session_no, ended_utc=st.get("utc"),
                     ended=status in ENDED, results=results)
    state["view"] = page_view(page, healthy, run_path, shown_events)
    return state


DOWNLOADS = (layout.CERTIFICATE_PDF, layout.CERTIFICATE_HTML, layout.CERTIFICATE_DCC,
             layout.RESULT)


def _title(run_path: Path) -> str:
    proc = read_mapping(run_path / layout.PROCEDURE)
    return str(proc.get("title") or run_path.name)


def list_runs(runs: Path) -> list[dict[str, JsonLike]]:
    """Every run directory in the runs folder, newest first, with its status and, for a
    run that did not pass, its first cause."""
    out: list[dict[str, JsonLike]] = []
    try:
        dirs = [p for p in runs.iterdir() if (p / layout.EVENTS).is_file()]
    except FileNotFoundError:
        return []
    for p in sorted(dirs, key=lambda p: p.name, reverse=True):
        events = read_events(p)
        starts = ev.of_kind(events, ev.SessionStarted)
        st = run_status(events, p)
        out.append({"run": p.name, "title": _title(p), "status": st["status"],
                    "cause": st["cause"], "sessions": len(starts),
                    "started_utc": starts[0].utc if starts else None})
    return out
