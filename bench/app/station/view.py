"""What a run's page says, worded and rounded once, here.

The server writes this text into the HTML and the live page's script only puts the same
text in place as the state changes. So a page read without JavaScript (curl, a text
browser, a page saved with the run) says what the browser shows, and every figure is
printed by the certificate's rounding rule (U to two significant digits, the value to the
same decimal, unresolved magnitudes as "< limit": docs/certificate.md), never by a second
formatter in the script that would drift from it.

A finished run's page shows its end state: how it ended and why (the first cause, as the
bench's console said it), the progress it reached, and when each instrument was last
heard, as wall times; a live view's "N s ago" would only grow on a finished run.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from datetime import datetime
from pathlib import Path

import msgspec

from bench.app.records.extract import frame_figures, kind_name
from bench.app.station.state import FOG_TAIL_S, AxisHealth, Health, PageState
from bench.core import events as ev
from bench.core import rundir_layout as layout
from bench.core.events import Event
from bench.core.plan import format_duration
from bench.core.yamlfile import read_mapping
from bench.kind import StationPart, declared_figures, installed
from bench.report.certificate.parts import verdict_label
from bench.report.certificate.rounding import (
    format_value_u,
)
from bench.report.certificate.sources import read_frame
from bench.report.figures import spec_for
from bench.report.result_frame import ResultFrame
from bench.report.station import StationParts, page_table, rate_text
from drivers.json_types import JsonLike

#: how each status reads on the page, for a run that has ended or stopped
ENDED_WORDS = {"passed": "Passed", "failed": "Failed", "refused": "Refused",
               "aborted": "Aborted", "incomplete": "Incomplete", "stopped": "Stopped",
               "ended": "Ended"}
#: docs/method.md D1-D2, as the certificate states them
U_NOTE = ("U: expanded uncertainty for about 95 %, k = t_95.45(ν_eff) of its budget "
          "(2.00 for infinite ν_eff; docs/method.md D1). 'value [lower, upper]': an "
          "asymmetric coverage interval; '< L': not resolved above its floor, L its "
          "one-sided upper limit (D2).")


# -- small words ----------------------------------------------------------------------------

def _utc_text(stamp: str | None) -> str:
    """An ISO UTC stamp as the page prints it: date and time to the second, no offset."""
    if not stamp:
        return "-"
    try:
        return datetime.fromisoformat(stamp).strftime("%Y-%m-%d %H:%M:%S")
    except ValueError:
        return str(stamp)[:19].replace("T", " ")


def _age(s: float | None) -> str:
    if s is None or not math.isfinite(s):
        return "-"
    return f"{s:.1f} s ago" if s < 10 else f"{s:.0f} s ago"


def _duration(s: float | None) -> str:
    return "-" if s is None or not math.isfinite(s) else format_duration(max(0.0, s))


# -- progress -------------------------------------------------------------------------------

def progress_view(state: PageState) -> dict[str, JsonLike]:
    """The step line, the line beneath it and the bar (0 to 1); for a finished run how it
    ended, with the first cause, and the bar where the run got to (full once the plan
    completed: the engine journals `completed` only then)."""
    prog = state.progress
    status = state.status
    steps, done = prog.steps, prog.steps_done
    step = prog.step
    cause = state.cause
    if status in ("running", "created"):
        if step is not None:
            line = f"Step {step.number} of {steps}: {step.words}"
        else:
            line = "not started" if status == "created" else "starting: no step yet"
        speed = prog.speed
        speed_text = (f" (measured speed {speed:.1f} bench s per wall s)" if speed else "")
        detail = (f"{done} of {steps} steps done; bench time left "
                  f"{_duration(prog.bench_left_s)}, wall time left "
                  f"{_duration(prog.wall_left_s)}{speed_text}")
        return {"value": float(prog.fraction) if prog.fraction else 0.0, "line": line,
                "detail": detail, "complete": False, "later": []}
    completed = prog.completed
    where = (f"{'after' if step.done else 'at'} step {step.number} of {steps} "
             f"({step.words})" if step is not None else "before the first step")
    word = ENDED_WORDS.get(status, status.capitalize())
    if status in ("passed", "failed"):
        line = (f"Completed: all {steps} steps done; the run {status}" if steps
                else f"Completed: nothing was left to do; the run {status}")
    elif status == "refused":
        line = f"Refused before anything moved: {cause}"
    elif status == "incomplete" and completed:
        line = f"Incomplete after all {steps} steps: {cause}"
    else:
        line = f"{word} {where}: {cause}" if cause else f"{word} {where}"
    parts = ([f"{done} of {steps} steps done"] if steps else ["no step was run"])
    if state.sessions > 1:
        parts[0] += f" in session {state.session} of {state.sessions}"
    if state.ended_utc:
        parts.append(f"ended {_utc_text(state.ended_utc)} UTC")
    if steps and prog.bench_time_s:
        parts.append(f"bench time {_duration(prog.bench_time_s)}")
    value = 1.0 if completed else (done / steps if steps else 0.0)
    return {"value": value, "line": line, "detail": "; ".join(parts),
            "complete": completed,
            "later": [f"also, while stopping: {x}" for x in state.later]}


# -- health -----------------------------------------------------------------------------------

def _tail_counts(a: AxisHealth) -> str:
    """'CRC errors / frames lost' of the FOG tail, '-' when none was read for the axis."""
    crc = a.fog_tail_crc_errors
    if crc is None or isinstance(crc, msgspec.UnsetType):
        return "-"
    lost = a.fog_tail_lost_frames
    return f"{crc} / {None if isinstance(lost, msgspec.UnsetType) else lost}"


def health_view(health: Health, status: str) -> dict[str, JsonLike]:
    """While running: how long since each instrument was heard, with warnings. Otherwise
    the instruments' last state: the counts as they were and the wall time (UTC) each
    was last heard; no warning, since a finished run's files are quiet by design."""
    running = status == "running"
    rows = []
    instruments = ("fog", "drive", "counter")
    for a in health.axes:
        if running:
            heard = [_age(a.age_s(i)) for i in instruments]
        else:
            heard = [_utc_text(a.utc(i)) for i in instruments]
        rows.append([a.axis, heard[0], str(a.fog_lost_in_halves), _tail_counts(a),
                     heard[1], heard[2]])
    when = "" if running else " (UTC)"
    # the tail's length is the live read's (live.py FOG_TAIL_S), as the page always said
    header = ["axis", f"FOG last data{when}", "FOG frames lost (timed halves)",
              f"FOG CRC errors / frames lost, last {FOG_TAIL_S:g} s of record",
              "drive last heard (heartbeat, feedback)" if running
              else "drive last heard (UTC; heartbeat, feedback)", f"counter last reading{when}"]
    if running:
        last = health.last_update_s
        note = ("" if last is None else
                f"- last update {_age(last)}{' (STALE)' if health.stale else ''}")
        title = "Health"
    else:
        title = ("Instruments when last heard" if status in ("stopped", "created")
                 else "Instruments at the end of the run")
        note = (f"- files last written {_utc_text(health.last_update_utc)} UTC"
                if health.last_update_utc else "")
    return {"title": title, "note": note, "header": header, "rows": rows,
            "warnings": list(health.warnings) if running else [],
            "stale": health.stale and running}


# -- results ----------------------------------------------------------------------------------

NEUTRAL = StationParts()


def station_of(kind: str | None) -> StationPart:
    """The kind's station part (the neutral one for a kind not installed here)."""
    found = installed(kind)
    return found.station if found is not None else NEUTRAL


_NAMED: dict[Path, str] = {}


def _procedure_named(run_path: Path) -> str | None:
    """The kind the run's procedure file names (a running run has no result.json yet),
    read once per run (the live stream asks every second)."""
    if run_path not in _NAMED:
        name = read_mapping(run_path / layout.PROCEDURE).get("procedure")
        if not name:
            return None
        _NAMED[run_path] = str(name)
    return _NAMED[run_path]


def _declared_table(frame: ResultFrame, kind: str) -> list[dict[str, JsonLike]]:
    """Any other kind: the figures it declares (bench.report.figures), each with its U and
    its check's verdict, in the words and units the kind gives them."""
    specs = declared_figures([kind]) if kind else ()
    rows = []
    for f in frame_figures(frame, kind) if kind else []:
        spec = spec_for(f.quantity, specs)
        scale, unit = (spec.scale, spec.shown) if spec is not None else (1.0, f.unit)
        words = spec.name if spec is not None else f.quantity
        shown = format_value_u(f.value, f.u, scale, signed=True)
        text = (f"< {shown.value}" if f.is_limit else
                f"{shown.value} (no U)" if shown.u is None else shown.joined())
        where = " ".join(x for x in (f.axis, "" if f.set_rate_dps is None
                                     else f"{rate_text(f.set_rate_dps)} deg/s") if x)
        rows.append(([where or "-", f"{words}, {unit}" if unit not in ("", "1") else words,
                      text, verdict_label(f.verdict) if f.verdict else "-"],
                     str(f.verdict or "")))
    if not rows:
        return []
    return [page_table("figures", "Results",
                       ("where", "quantity, unit", "value ± U", "verdict"), rows)]


@functools.lru_cache(maxsize=64)
def _final(path: str, _mtime_ns: int, _size: int
           ) -> tuple[str | None, tuple[dict[str, JsonLike], ...]]:
    """result.json's verdict and tables, once per version of the file (the live stream
    asks every second; the file changes only when an analysis writes it again)."""
    frame = read_frame(Path(path) / layout.RESULT)
    if frame is None or not frame.doc:
        return None, ()
    kind = frame.procedure or kind_name(frame, Path(path))
    tables = station_of(kind).result_tables(frame) or _declared_table(frame, kind)
    return frame.verdict, tuple(tables)


def final_view(run_path: Path) -> tuple[str | None, list[dict[str, JsonLike]]] | None:
    """result.json's verdict and tables, or None when there is none."""
    try:
        st = (run_path / layout.RESULT).stat()
    except OSError:
        return None
    verdict, tables = _final(str(run_path), st.st_mtime_ns, st.st_size)
    return verdict, list(tables)


def results_view(state: PageState, run_path: Path) -> dict[str, JsonLike]:
    """The results section: while running, the first look per pair; once the run has
    ended, result.json's verdict and tables (the certificate prints these figures)."""
    live = state.results
    # result.json is this session's only once it has ended (a session stopped or refused
    # under it leaves an earlier session's analysis there)
    final = final_view(run_path) if state.ended and state.status != "refused" else None
    if final is not None and final[1]:
        verdict, tables = final
        return {"title": "Final results (result.json; the certificate prints these figures)",
                "verdict": verdict_label(verdict) if verdict else None, "final": True,
                "tables": tables, "note": U_NOTE}
    if state.status == "refused":
        none = "nothing was measured: the run was refused before anything moved"
    elif final is not None:
        none = "result.json holds no figures this page can show"
    else:
        none = "no pair analysed yet"
    return {"title": "Results", "final": False,
            "verdict": (verdict_label(final[0]) if final is not None and final[0] else None),
            "tables": [table] if live and (table := station_of(
                _procedure_named(run_path)).live_table(live)) is not None else [],
            "note": U_NOTE if live else none}


# -- the log ----------------------------------------------------------------------------------

def log_line(e: Event) -> str:
    """One milestone, fault or prompt as the page lists it (a kind's own events in its
    own words, `Event.log_text`)."""
    said = e.log_text()
    if said is None:
        said = e.kind
        reason = getattr(e, "reason", None)
        if reason:
            said += f" - {reason}"
        if isinstance(e, ev.Prompted) and e.text:
            said += f" - {e.text} ({e.answered})"
        elif isinstance(e, ev.RecordsOverdue | ev.OutOfControl) and e.text:
            said += f" - {e.text} ()"
        if isinstance(e, ev.Exited):
            said += f" with status {e.status}"
            # 3 without a cause is not an abort at the bench (live.py `ending`)
            how = {0: "passed", 1: "failed", 2: "refused",
                   3: "aborted" if e.cause else None}.get(e.status)
            said += f" ({how})" if how else ""
            if e.cause:
                said += f" - {e.cause}"
        error = getattr(e, "error", None)
        if error:
            said += f" ({error})"
    return f"{e.utc[11:19]} UTC, session {e.session}: {said}"


# -- the page ---------------------------------------------------------------------------------

def page_view(state: PageState, health: Health, run_path: Path, log: Sequence[Event]
              ) -> dict[str, JsonLike]:
    """Everything the run's page prints, from the state `live_state` reads and the events
    its log shows."""
    status = state.status
    return {
        "progress": progress_view(state),
        "health": health_view(health, status),
        "results": results_view(state, run_path),
        "log": [{"event": e.kind, "text": log_line(e)} for e in log],
        # the charts show what a step recorded: none for a run refused before its first
        "charts": status in ("running", "created") or state.progress.step is not None,
        "live": status in ("running", "created"),
    }
