"""Free disk space against what a run will write, checked before anything moves.

A day-long run that stops on a full disk wastes the day; the raw FOG capture dominates
(frame bytes x output rate x bench time per axis), so that is what is estimated.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

from bench.config import FogSettings
from drivers.fog_formats import get_format

#: drive, counter and event logs per axis and bench second (the demo writes ~0.2 kB/s)
LOG_BYTES_PER_AXIS_S = 1000.0
#: what is kept free beyond the estimate (result.json, certificate, plots)
RESERVE_BYTES = 20 * 1024 * 1024
#: the estimate is multiplied by this (settling and retries run longer than planned)
SAFETY = 1.25


def expected_raw_bytes(stand: dict[str, Any], axes: list[str], bench_s: float) -> float:
    """Bytes the raw files of `axes` take for `bench_s` seconds of bench time."""
    total = 0.0
    for name in axes:
        fog = FogSettings.of_axis(stand, name)
        per_s = LOG_BYTES_PER_AXIS_S
        if fog:
            try:
                frame = get_format(fog.format).size
            except (KeyError, ValueError):
                frame = 64
            per_s += fog.rate_hz * frame
        total += per_s * bench_s
    return total


def space_problem(folder: Path, expected_bytes: float) -> str | None:
    """Why `folder`'s file system cannot hold the run, or None."""
    need = SAFETY * expected_bytes + RESERVE_BYTES
    free = shutil.disk_usage(folder).free
    if free >= need:
        return None
    mb = 1024 * 1024
    return (f"not enough free space in {folder}: {free / mb:.1f} MB free, the plan's raw "
            f"data need about {expected_bytes / mb:.1f} MB (+{SAFETY - 1:.0%} and "
            f"{RESERVE_BYTES / mb:.0f} MB kept free); nothing was moved")
