"""Conditions the bench measured: the FOG's own temperature over each half (every KVH frame
carries it; 1775 IMU Technical Manual, table 5-1: an integer, deg C), min / mean / max per
half and per axis, added to result.json as `conditions_measured` (an addition).

Read from the raw captures with the analysis's own reader (drivers.fog.CaptureCursor,
chunk by chunk: memory flat in run length), starting at each half's decoder checkpoint.
It is the table-top temperature at the FOG, not the room's: the certificate says so.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from bench.core.config import Config
from bench.core.journal import RunDir
from drivers.fog import CaptureCursor
from procedures.rate_ladder.events import HalfAcquired


def _half_temperature(path: Path, f: Any, h: HalfAcquired) -> dict[str, Any] | None:
    lo, hi, total, n = math.inf, -math.inf, 0.0, 0
    cursor = CaptureCursor(path, fmt=f.format, axis=f.axis, rate_hz=f.rate_hz, units=f.units,
                           start=h.fog_capture if h.fog_capture and
                           h.fog_capture.get("last_index", h.fog_from) < h.fog_from else None)
    try:
        for s in cursor.window(h.fog_from, h.fog_to):
            t = s.temperature[s.received & np.isfinite(s.temperature)]
            if t.size:
                lo, hi = min(lo, float(t.min())), max(hi, float(t.max()))
                total, n = total + float(t.sum()), n + int(t.size)
    finally:
        cursor.close()
    if n == 0:
        return None
    return {"set_rate_dps": h.set_rate_dps, "half": h.half, "session": h.session,
            "samples": n, "min_c": lo, "mean_c": total / n, "max_c": hi}


def fog_temperatures(run: RunDir, cfg: Config) -> dict[str, Any]:
    """{axis: {halves: [...], min_c, mean_c, max_c}} from every half recorded."""
    out: dict[str, Any] = {}
    for h in HalfAcquired.all_in(run.events()):
        path = run.path / "raw" / f"s{h.session}" / f"{h.axis}-fog.bin"
        if not path.is_file():
            continue
        try:
            found = _half_temperature(path, cfg.fog(h.axis), h)
        except (OSError, ValueError):
            found = None          # a damaged capture: the analysis reports it; not measured
        if found is not None:
            out.setdefault(h.axis, {"halves": []})["halves"].append(found)
    for ax in out.values():
        halves = ax["halves"]
        n = sum(x["samples"] for x in halves)
        ax.update(min_c=min(x["min_c"] for x in halves), max_c=max(x["max_c"] for x in halves),
                  mean_c=sum(x["mean_c"] * x["samples"] for x in halves) / n)
    return out


def add_conditions(result: dict[str, Any], run: RunDir, cfg: Config) -> dict[str, Any]:
    temps = fog_temperatures(run, cfg)
    result["conditions_measured"] = {
        "fog_temperature": {"source": "FOG frames' temperature field (table top, at the "
                                      "FOG), deg C, integer resolution", "axes": temps}
        if temps else None,
        "room": None,      # no room sensor on this stand: not measured
    }
    return result
