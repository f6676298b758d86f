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

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bench.config import FogSettings
from drivers.fog import dps_per_unit
from drivers.fog_formats import AXES, DecodeState, decode, get_format

FULL_TURN_DEG = 360.0             # one zero mark per turn (docs/method.md A1)
TRACE_POINTS = 600                # a plot of a half never needs more points than pixels
FOG_TAIL_S = 30.0                 # bench seconds of FOG record shown
DRIVE_TAIL_BYTES = 96 * 1024      # about 600 feedback readings
EVENT_KINDS_SHOWN = ("abort", "safe_stop", "prompt", "completed", "exit", "session_start",
                     "pair", "settled")


def tail_jsonl(path: Path, max_bytes: int) -> list[dict[str, Any]]:
    """The whole records in the last `max_bytes` of a JSON-lines file (first and torn
    last lines skipped): a growing raw log is read in constant time."""
    try:
        size = path.stat().st_size
        with open(path, "rb") as f:
            start = max(0, size - max_bytes)
            f.seek(start)
            data = f.read(size - start)
    except FileNotFoundError:
        return []
    lines = data.split(b"\n")
    if start > 0:
        lines = lines[1:]
    out = []
    for line in lines:
        try:
            out.append(json.loads(line))
        except (json.JSONDecodeError, UnicodeDecodeError):
            continue
    return out


def read_events(run_path: Path) -> list[dict[str, Any]]:
    """Every event of the run (all sessions); a torn last line is skipped."""
    return tail_jsonl(run_path / "events.jsonl", 1 << 62)


def pid_alive(pid: int | None) -> bool:
    if not pid:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


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


def fog_trace(raw: Path, fog: FogSettings, tail_s: float = FOG_TAIL_S
              ) -> dict[str, list[float]]:
    """The last `tail_s` of a FOG capture, decoded and decimated (bench time, deg/s).

    Time is the frame's position in the capture over the output rate: exact while no
    bytes were lost, a few frames off after a corrupt stretch, which a live plot can bear.
    """
    try:
        f = get_format(fog.format)
        size = raw.stat().st_size
    except (FileNotFoundError, ValueError, KeyError):
        return {"t_s": [], "rate_dps": []}
    want = int(tail_s * fog.rate_hz) * f.size
    start = max(0, size - want)
    with open(raw, "rb") as fh:
        fh.seek(start)
        buf = fh.read(size - start)
    frames, _, _ = decode(buf, f, DecodeState(offset=start))
    if not len(frames) or fog.axis not in AXES:
        return {"t_s": [], "rate_dps": []}
    scale = dps_per_unit(fog.units, fog.rate_hz)
    t = frames.offset.astype(np.float64) / f.size / fog.rate_hz
    y = frames.rates[:, AXES.index(fog.axis)].astype(np.float64) * scale
    ts, ys = decimate(t, y)
    return {"t_s": ts, "rate_dps": ys}


def drive_trace(raw: Path) -> dict[str, list[float]]:
    """The drive's recent velocity feedback (TPDO), for the settling plot."""
    recs = [r for r in tail_jsonl(raw, DRIVE_TAIL_BYTES) if r.get("kind") == "feedback"]
    return {"t_s": [float(r["t_s"]) for r in recs if r.get("t_s") is not None],
            "velocity_dps": [float(r["velocity_dps"]) for r in recs if r.get("t_s") is not None]}


def turn_rates(acquire: dict[str, Any]) -> dict[str, Any]:
    """Per-turn rates of one timed half from its zero-mark edges (docs/method.md A1: w = 360/T,
    signed as commanded) and their deviation from the set rate (eq. 1, per turn)."""
    edges = np.asarray(acquire.get("edges_s") or [], dtype=np.float64)
    set_dps = float(acquire.get("set_rate_dps", 0.0))
    if edges.size < 2 or set_dps == 0:
        return {"set_rate_dps": set_dps, "rate_dps": [], "deviation_ppm": []}
    rate_dps = math.copysign(1.0, set_dps) * FULL_TURN_DEG / np.diff(edges)
    dev_ppm = (rate_dps - set_dps) / set_dps * 1e6
    return {"set_rate_dps": set_dps, "axis": acquire.get("axis"), "unit": acquire.get("unit"),
            "rate_dps": [float(v) for v in rate_dps],
            "deviation_ppm": [float(v) for v in dev_ppm]}


def _utc_s(stamp: str) -> float:
    from datetime import datetime
    return datetime.fromisoformat(stamp).timestamp()


def progress_of(session: list[dict[str, Any]]) -> dict[str, Any]:
    """Step, progress and ETA of one session, in bench time and in wall time.

    The wall ETA is the bench time left over the speed measured so far in this session
    (bench seconds per wall second between its first and latest event), never the clock
    speed configured: a loaded machine or a twin-paced clock changes the speed.
    """
    plan = next((e for e in reversed(session) if e.get("event") == "plan"), None)
    steps = int(plan["steps"]) if plan else 0
    estimates = list(plan.get("step_estimates_s") or []) if plan else []
    total_s = float(plan["estimate_s"]) if plan else 0.0
    starts = [e for e in session if e.get("event") == "step_start"]
    done = {e.get("index") for e in session if e.get("event") == "step_done"}
    cur = starts[-1] if starts else None
    timed = [e for e in session if e.get("t_s") is not None and e.get("utc")]
    now_bench = float(timed[-1]["t_s"]) if timed else 0.0
    speed = None
    if len(timed) >= 2:
        dt_wall = _utc_s(timed[-1]["utc"]) - _utc_s(timed[0]["utc"])
        dt_bench = float(timed[-1]["t_s"]) - float(timed[0]["t_s"])
        if dt_wall > 0 and dt_bench > 0:
            speed = dt_bench / dt_wall
    left_s = None
    if cur is not None and estimates and len(estimates) == steps:
        i = int(cur["index"])
        left_s = sum(estimates[i:]) if i not in done else sum(estimates[i + 1:])
        if i not in done and cur.get("t_s") is not None:
            left_s -= min(estimates[i], max(0.0, now_bench - float(cur["t_s"])))
    elif total_s and cur is not None:
        left_s = total_s * (1 - len(done) / max(steps, 1))
    fraction = None
    if steps:
        fraction = len(done) / steps
        if left_s is not None and total_s > 0:
            fraction = min(1.0, max(0.0, 1 - left_s / total_s))
    return {
        "steps": steps,
        "steps_done": len(done),
        "step": None if cur is None else {
            "index": cur.get("index"), "number": int(cur.get("index", 0)) + 1,
            "action": cur.get("action"), "axis": cur.get("axis"), "unit": cur.get("unit"),
            "describe": cur.get("describe"), "done": cur.get("index") in done},
        "fraction": fraction,
        "bench_time_s": now_bench,
        "bench_left_s": left_s,
        "speed": speed,
        "wall_left_s": (left_s / speed) if (left_s is not None and speed) else None,
    }


def live_state(run_path: Path) -> dict[str, Any]:
    """The station's view of one run directory (JSON-ready)."""
    run_path = Path(run_path)
    events = read_events(run_path)
    starts = [e for e in events if e.get("event") == "session_start"]
    session_no = starts[-1].get("session") if starts else None
    session = [e for e in events if e.get("session") == session_no] if starts else []
    start = starts[-1] if starts else {}
    exit_ev = next((e for e in reversed(session) if e.get("event") == "exit"), None)
    pid = start.get("pid")
    if exit_ev is not None:
        status = {0: "passed", 1: "failed", 2: "invalid", 3: "aborted"}.get(
            exit_ev.get("status"), "ended")
    elif not starts:
        status = "created"
    elif pid is not None and not pid_alive(pid):
        status = "stopped (the bench process is gone; resume it)"
    else:
        status = "running"
    try:
        stand = yaml.safe_load((run_path / "stand.yaml").read_text(encoding="utf-8")) or {}
    except (OSError, yaml.YAMLError):
        stand = {}
    prog = progress_of(session)
    axis = (prog["step"] or {}).get("axis")
    raw = run_path / "raw" / f"s{session_no}" if session_no else None
    fog: dict[str, list[float]] = {"t_s": [], "rate_dps": []}
    drive: dict[str, list[float]] = {"t_s": [], "velocity_dps": []}
    if raw is not None and axis:
        settings = FogSettings.of_axis(stand, axis) if isinstance(stand, dict) else None
        if settings is not None:
            fog = fog_trace(raw / f"{axis}-fog.bin", settings)
        drive = drive_trace(raw / f"{axis}-drive.jsonl")
    acquires = [e for e in events if e.get("event") == "acquire"]
    result = None
    if (run_path / "result.json").exists() and status != "running":
        try:
            result = json.loads((run_path / "result.json").read_text()).get("verdict")
        except (OSError, json.JSONDecodeError):
            result = None
    shown = [{k: v for k, v in e.items() if k not in ("traceback",)}
             for e in events if e.get("event") in EVENT_KINDS_SHOWN][-40:]
    ident = (stand.get("stand") or {}) if isinstance(stand, dict) else {}
    return {
        "run": run_path.name,
        "title": _title(run_path),
        "stand": {k: ident.get(k) for k in ("maker", "model", "serial")},
        "simulated": isinstance(stand, dict) and "sim" in stand,
        "status": status,
        "session": session_no,
        "sessions": len(starts),
        "pid": pid,
        "progress": prog,
        "turns": turn_rates(acquires[-1]) if acquires else None,
        "fog": {"axis": axis, **fog},
        "drive": {"axis": axis, **drive},
        "faults": [e for e in shown if e.get("event") in ("abort", "safe_stop")
                   and not e.get("ok", False)],
        "prompts": [e for e in shown if e.get("event") == "prompt"],
        "log": shown,
        "verdict": result,
        "files": [n for n in DOWNLOADS if (run_path / n).exists()],
    }


DOWNLOADS = ("certificate.pdf", "certificate.html", "certificate.dcc.xml", "result.json")


def _title(run_path: Path) -> str:
    try:
        proc = yaml.safe_load((run_path / "procedure.yaml").read_text(encoding="utf-8")) or {}
        return str(proc.get("title") or run_path.name) if isinstance(proc, dict) else run_path.name
    except (OSError, yaml.YAMLError):
        return run_path.name


def list_runs(runs: Path) -> list[dict[str, Any]]:
    """Every run directory in the runs folder, newest first, with its status."""
    out = []
    try:
        dirs = [p for p in runs.iterdir() if (p / "events.jsonl").is_file()]
    except FileNotFoundError:
        return []
    for p in sorted(dirs, key=lambda p: p.name, reverse=True):
        events = read_events(p)
        starts = [e for e in events if e.get("event") == "session_start"]
        last = starts[-1].get("session") if starts else None
        exit_ev = next((e for e in reversed(events) if e.get("event") == "exit"
                        and e.get("session") == last), None)
        if exit_ev is not None:
            status = {0: "passed", 1: "failed", 3: "aborted"}.get(exit_ev.get("status"), "ended")
        elif starts and pid_alive(starts[-1].get("pid")):
            status = "running"
        else:
            status = "stopped" if starts else "created"
        out.append({"run": p.name, "title": _title(p), "status": status,
                    "sessions": len(starts),
                    "started_utc": starts[0].get("utc") if starts else None})
    return out
