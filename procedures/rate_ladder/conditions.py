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
from typing import TypedDict

import numpy as np

from bench.core import rundir_layout as layout
from bench.core.config import Config, FogSettings
from bench.core.journal import RunDir, fog_capture_starts
from drivers.fog import CaptureCursor, FogSamples
from procedures.rate_ladder.events import HalfAcquired


class HalfTemperature(TypedDict):
    """A half's FOG temperature, as `conditions_measured` lists it."""

    set_rate_dps: float
    half: int
    session: int
    samples: int
    min_c: float
    mean_c: float
    max_c: float


class AxisTemperature(TypedDict):
    """An axis's halves and their span (the mean weighted by each half's samples)."""

    halves: list[HalfTemperature]
    min_c: float
    max_c: float
    mean_c: float


class TemperatureSpan:
    """min / mean / max of the FOG's temperature over a window, fed chunk by chunk (the
    same chunks, in the same order, wherever it is fed: the sums come out bit for bit)."""

    def __init__(self) -> None:
        self.lo, self.hi, self.total, self.n = math.inf, -math.inf, 0.0, 0

    def add(self, s: FogSamples) -> None:
        t = s.temperature[s.received & np.isfinite(s.temperature)]
        if t.size:
            self.lo, self.hi = min(self.lo, float(t.min())), max(self.hi, float(t.max()))
            self.total, self.n = self.total + float(t.sum()), self.n + int(t.size)

    def of_half(self, h: HalfAcquired) -> HalfTemperature | None:
        if self.n == 0:
            return None
        return {"set_rate_dps": h.set_rate_dps, "half": h.half, "session": h.session,
                "samples": self.n, "min_c": self.lo, "mean_c": self.total / self.n,
                "max_c": self.hi}


def memo_key(session: int, axis: str, i_from: int, i_to: int) -> str:
    """RunDir.memo's key of a window's temperature span (the analysis decodes the window
    and keeps its span: this module need not decode it again)."""
    return f"rate-ladder temperature s{session} {axis} {i_from}..{i_to}"


def _half_temperature(path: Path, f: FogSettings, h: HalfAcquired, first_index: int | None
                      ) -> HalfTemperature | None:
    span = TemperatureSpan()
    cursor = CaptureCursor(path, fmt=f.format, axis=f.axis, rate_hz=f.rate_hz, units=f.units,
                           start=h.fog_capture if h.fog_capture and
                           h.fog_capture.get("last_index", h.fog_from) < h.fog_from else None,
                           first_index=first_index)
    try:
        for s in cursor.window(h.fog_from, h.fog_to):
            span.add(s)
    finally:
        cursor.close()
    return span.of_half(h)


def fog_temperatures(run: RunDir, cfg: Config) -> dict[str, AxisTemperature]:
    """{axis: {halves: [...], min_c, mean_c, max_c}} from every half recorded."""
    by_axis: dict[str, list[HalfTemperature]] = {}
    events = run.events()
    first = fog_capture_starts(events)
    for h in HalfAcquired.all_in(events):
        path = layout.raw_file(run.path, h.session, layout.fog_capture(h.axis))
        if not path.is_file():
            continue
        try:
            span = run.memo.pop(memo_key(h.session, h.axis, h.fog_from, h.fog_to), None)
            found = span.of_half(h) if isinstance(span, TemperatureSpan) \
                else _half_temperature(path, cfg.fog(h.axis), h, first.get((h.session, h.axis)))
        except (OSError, ValueError):
            found = None          # a damaged capture: the analysis reports it; not measured
        if found is not None:
            by_axis.setdefault(h.axis, []).append(found)
    return {axis: AxisTemperature(
                halves=halves, min_c=min(x["min_c"] for x in halves),
                max_c=max(x["max_c"] for x in halves),
                mean_c=sum(x["mean_c"] * x["samples"] for x in halves)
                / sum(x["samples"] for x in halves))
            for axis, halves in by_axis.items()}

