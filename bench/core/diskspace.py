"""Free disk space against what a run will write, checked before anything moves.

A day-long run that stops on a full disk wastes the day; the raw FOG capture dominates
(frame bytes x output rate x bench time per axis), so that is what is estimated.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from bench.core.config import FogSettings, StandSettings
from drivers.fog_formats import get_format

#: drive, counter and event logs per axis and bench second (the demo writes ~0.2 kB/s)
LOG_BYTES_PER_AXIS_S = 1000.0
#: what is kept free beyond the estimate (result.json, certificate, plots)
RESERVE_BYTES = 20 * 1024 * 1024
#: the estimate is multiplied by this (settling and retries run longer than planned)
SAFETY = 1.25
#: a frame format the bench does not know yet (the schema leaves fog.format open)
UNKNOWN_FRAME_BYTES = 64


def expected_raw_bytes(stand: StandSettings, axes: list[str], bench_s: float) -> float:
    """Bytes the raw files of `axes` take for `bench_s` seconds of bench time."""
    total = 0.0
    for name in axes:
        fog = stand.axes[name].fog
        per_s = LOG_BYTES_PER_AXIS_S
        if fog:
            per_s += fog.rate_hz * _frame_bytes(fog)
        total += per_s * bench_s
    return total


def format_bytes(n: float) -> str:
    """Bytes in the unit an operator reads (kB, MB, GB; 1000-based, as df -H)."""
    for unit, size in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if abs(n) >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


def data_volume_lines(stand: StandSettings, axes: list[str], bench_s: float,
                      folder: Path) -> list[str]:
    """What `bench plan` says about the raw data: per axis and in total, against the
    free space of the runs folder (the same figures `bench run` checks before starting)."""
    out = []
    for name in axes:
        fog = stand.axes[name].fog
        what = (f"FOG {fog.rate_hz:g} Hz x {_frame_bytes(fog)} B frames + logs" if fog
                else "logs")
        out.append(f"  {name}: {format_bytes(expected_raw_bytes(stand, [name], bench_s))} "
                   f"({what}, for the whole {bench_s / 3600:.3g} h)")
    total = expected_raw_bytes(stand, axes, bench_s)
    need = SAFETY * total + RESERVE_BYTES
    where = existing_folder(folder)
    free = shutil.disk_usage(where).free
    verdict = "enough" if free >= need else "NOT ENOUGH: bench run will refuse to start"
    return [f"Raw data: about {format_bytes(total)}", *out,
            f"  needs {format_bytes(need)} free with the margin (+{SAFETY - 1:.0%} and "
            f"{format_bytes(RESERVE_BYTES)}); {where} has {format_bytes(free)}: {verdict}"]


def existing_folder(folder: Path) -> Path:
    """`folder`, or its nearest existing parent (the runs folder may not exist yet)."""
    p = Path(folder).absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _frame_bytes(fog: FogSettings) -> int:
    try:
        return get_format(fog.format).size
    except (KeyError, ValueError):
        return UNKNOWN_FRAME_BYTES


def space_problem(folder: Path, expected_bytes: float) -> str | None:
    """Why `folder`'s file system cannot hold the run, or None."""
    need = SAFETY * expected_bytes + RESERVE_BYTES
    free = shutil.disk_usage(existing_folder(folder)).free
    if free >= need:
        return None
    return (f"not enough free space in {folder}: {format_bytes(free)} free, the plan's raw "
            f"data need about {format_bytes(expected_bytes)}, {format_bytes(need)} with the "
            f"margin (+{SAFETY - 1:.0%} and {format_bytes(RESERVE_BYTES)} kept free); free "
            f"{format_bytes(need - free)} or choose another --out; nothing was moved")
