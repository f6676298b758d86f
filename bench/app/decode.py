"""`bench decode RAW_FILE --format NAME [--csv OUT]` (CONTRACT §1).

Decodes a raw FOG capture offline with the same stream decoder the live driver runs,
in the same kind of pieces, so what it prints is what the run saw: frames, CRC
failures, sequence gaps (each with its first lost index and count), bytes that were
no frame, and a cut-off frame at the end. Sample indices start where the capture did:
`--first-index N`, or, for a file in a run directory (raw/s<k>/<axis>-fog.bin), its
session's `fog_capture` event (the ladder opens an axis's FOG for its own steps, at
clock t, and the capture starts at sample ceil(t * rate), drivers/fog.py); else 0.
Exit status: 0 a clean capture, 1 decoded
but with CRC failures or lost frames, or no frame at all (then every known format is
tried and named), 2 the file or the format is invalid.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TextIO

import numpy as np

from bench.core import rundir_layout as layout
from bench.core.journal import fog_capture_starts, read_events
from drivers.fog_formats import FORMATS, DecodeState, Frames, StreamDecoder

_CHUNK_BYTES = 1 << 22
_EVENTS_SHOWN = 20


def run_capture_start(path: Path) -> int | None:
    """The first index of a capture inside a run directory, from its events (or None)."""
    capture = layout.fog_capture_of(path)
    if capture is None:
        return None
    run, session, axis = capture
    events = run / layout.EVENTS
    if not events.is_file():
        return None
    try:
        return fog_capture_starts(read_events(events)).get((session, axis))
    except (OSError, ValueError, KeyError):
        return None


def decode_command(raw_file: str, fmt: str, csv_path: str | None,
                   first_index: int | None = None) -> int:
    if fmt not in FORMATS:
        print(f"bench decode: unknown format {fmt!r} (known: {', '.join(sorted(FORMATS))})",
              file=sys.stderr)
        return 2
    path = Path(raw_file)
    if not path.is_file():
        print(f"bench decode: {raw_file}: no such file", file=sys.stderr)
        return 2
    if first_index is None:
        first_index = run_capture_start(path)
        if first_index is not None:
            print(f"first index: {first_index} (the run's fog_capture event)")
    dec = StreamDecoder(fmt)
    dec.state = DecodeState.starting_at(first_index)
    out: TextIO | None = None
    try:
        if csv_path is not None:
            out = open(csv_path, "w", newline="")  # noqa: SIM115 (closed below)
            out.write(",".join(csv_columns(dec)) + "\n")
        with open(path, "rb") as f:
            while chunk := f.read(_CHUNK_BYTES):
                frames = dec.feed(chunk)
                if out is not None and len(frames):
                    write_csv_rows(out, frames, dec)
    except OSError as e:
        print(f"bench decode: {e}", file=sys.stderr)
        return 2
    finally:
        if out is not None:
            out.close()
    print_summary(dec, path)
    if dec.frames == 0:
        print(f"bench decode: no frame of format {fmt} in {path} ({dec.bytes} bytes); "
              f"{other_formats(path, fmt)}", file=sys.stderr)
        return 1
    return 1 if dec.crc_errors or dec.lost_frames else 0


def other_formats(path: Path, tried: str) -> str:
    """Which other formats the start of the capture decodes as (the likely mix-up)."""
    with open(path, "rb") as f:
        head = f.read(_CHUNK_BYTES)
    found = []
    for name in sorted(FORMATS):
        if name != tried:
            d = StreamDecoder(name)
            d.feed(head)
            found.append(f"{name}: {d.frames} frame(s)")
    tried_all = ", ".join(sorted(FORMATS))
    hits = [f for f in found if not f.endswith(": 0 frame(s)")]
    if hits:
        return f"formats tried: {tried_all}; the first {len(head)} bytes decode as " \
               f"{'; '.join(hits)}: give that --format"
    return f"formats tried: {tried_all}; none decodes any frame (not a FOG capture?)"


def csv_columns(dec: StreamDecoder) -> list[str]:
    return ["index", "sequence", "status", "x", "y", "z", "temperature",
            *dec.format.extra_fields, "offset"]


def write_csv_rows(out: TextIO, frames: Frames, dec: StreamDecoder) -> None:
    """Rates as the frames carry them; 9 significant digits give float32 back exactly."""
    cols: list[np.ndarray] = [frames.index, frames.sequence, frames.status,
                              *frames.rates.T, frames.temperature,
                              *(frames.extra[n] for n in dec.format.extra_fields),
                              frames.offset]
    fmts = ["%d", "%d", "%d", "%.9g", "%.9g", "%.9g", "%d",
            *("%d" if frames.extra[n].dtype.kind in "iu" else "%.9g"
              for n in dec.format.extra_fields), "%d"]
    table = np.empty((len(frames), len(cols)), dtype=object)
    for k, c in enumerate(cols):
        table[:, k] = c
    np.savetxt(out, table, fmt=fmts, delimiter=",")


def print_summary(dec: StreamDecoder, path: Path) -> None:
    print(f"file: {path}")
    print(f"format: {dec.format.name}")
    print(f"bytes: {dec.bytes}")
    print(f"frames: {dec.frames}")
    print(f"crc_errors: {dec.crc_errors}")
    print(f"gaps: {dec.gaps}")
    print(f"lost_frames: {dec.lost_frames}")
    print(f"skipped_bytes: {dec.skipped_bytes}")
    print(f"trailing_bytes: {len(dec.leftover)}")
    if dec.frames:   # from where the capture starts (its first_index) to the last frame
        print(f"index_range: {dec.state.first_index or 0} .. {dec.state.last_index}")
    for i, n in dec.gap_events[:_EVENTS_SHOWN]:
        print(f"gap: index {i}, {n} frame{'s' if n != 1 else ''} lost")
    for i, off in dec.crc_events[:_EVENTS_SHOWN]:
        print(f"crc_error: at byte {off}, index >= {i}")
    hidden = max(len(dec.gap_events), len(dec.crc_events)) - _EVENTS_SHOWN
    if hidden > 0:
        print(f"... {hidden} more events (see --csv for every frame)")
