"""A pair analysed from the raw capture in chunks equals the in-memory analysis exactly.

The capture is the FOG's own bytes (KVH format A frames of a simulated stand, with a
dropped and a broken frame); the in-memory path decodes it whole (`read_capture`, as
`bench analyze` did), the chunked path reads it forward in small pieces into files the
analysis reads chunk by chunk (drivers.fog.CaptureCursor, bench.analysis.disk).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import procedures.rate_ladder.analysis as ladder_analysis
from bench.analysis import CounterBudget, HalfRecord, analyze_pair
from bench.analysis.disk import DiskArray
from bench.core.journal import RunDir
from bench.core.loader import load_config
from bench.report.codec import encode
from drivers.fog import CaptureCursor, read_capture
from drivers.fog_formats import StreamDecoder, get_format
from procedures.rate_ladder.analysis import (
    pair_summary,
    read_half_ahead,
    static_record,
    unit_halves,
    window_on_disk,
)
from procedures.rate_ladder.events import HalfAcquired
from procedures.rate_ladder.result import pair_entry, rate_entry
from tests.conftest import DemoRun
from tests.test_analysis_sim import paper_axis, simulate_pair

RATE_HZ = 1000.0


def _capture(path: Path, fog_dps: np.ndarray, lost: int, broken: int) -> None:
    """The frames a FOG sends for these samples, one lost and one broken."""
    fmt = get_format("kvh-a")
    n = fog_dps.size
    rates = np.zeros((n, 3), dtype=np.float32)
    rates[:, 2] = fog_dps.astype(np.float32)
    rows = fmt.encode(np.arange(n), rates, temperature=25).copy()
    rows[broken, 14] ^= 0x5A
    keep = np.ones(n, dtype=bool)
    keep[lost] = False
    path.write_bytes(rows[keep].tobytes())


def _as_json(pa) -> str:
    return json.dumps([encode(rate_entry(r)) for r in pa.rates] + [encode(pair_entry(pa.pair))],
                      sort_keys=True, default=str)


@pytest.mark.timeout(60)
def test_a_pair_from_the_capture_in_chunks_equals_the_in_memory_analysis(
        tmp_path: Path) -> None:
    sp = simulate_pair(paper_axis(), 100.0, 3, seed=5)
    n_total = sp.halves[0].fog_dps.size
    kw = dict(fog_rate_hz=RATE_HZ, counter_budget=CounterBudget(), harmonics=2,
              mains_hz=50.0)
    # the windows a run would log: each half's whole turns and a sample either side
    spans = [(int(np.floor(h.edge_times_s[0] * RATE_HZ)),
              int(np.floor(h.edge_times_s[-1] * RATE_HZ)) + 2) for h in sp.halves]
    raw = tmp_path / "outer-fog.bin"
    _capture(raw, sp.halves[0].fog_dps, lost=spans[0][0] + 500, broken=spans[1][0] + 1000)

    whole, _ = read_capture(raw, rate_hz=RATE_HZ)
    in_memory = []
    for h, (a, b) in zip(sp.halves, spans, strict=True):
        ok = whole.valid[a:b]
        in_memory.append(HalfRecord(h.sign, h.edge_times_s, whole.t_s[a:b][ok],
                                    whole.rate_dps[a:b][ok]))
    assert sum(r.fog_t_s.size for r in in_memory) < sum(b - a for a, b in spans)  # the gaps

    # chunked: a cursor through the file in 64 kB reads, windows of 4096 samples
    cursor = CaptureCursor(raw, rate_hz=RATE_HZ, chunk_bytes=1 << 16)
    on_disk = []
    for i, (h, (a, b)) in enumerate(zip(sp.halves, spans, strict=True)):
        t, f = window_on_disk(cursor, a, b, tmp_path / f"w{i}")
        assert isinstance(t, DiskArray) and t.size == in_memory[i].fog_t_s.size
        on_disk.append(HalfRecord(h.sign, h.edge_times_s, t, f))
    expected = _as_json(analyze_pair(in_memory, 100.0, chunk=4096, **kw))
    assert _as_json(analyze_pair(on_disk, 100.0, chunk=4096, **kw)) == expected

    # a cursor started at a decoder checkpoint part way in (what a run logs per half)
    dec = StreamDecoder("kvh-a")
    data = raw.read_bytes()
    dec.feed(data[:(spans[1][0] - 300) * 36 + 17])
    state = dec.state
    mark = {"offset": state.offset, "last_index": state.last_index,
            "last_sequence": state.last_sequence, "last_end": state.last_end}
    late = CaptureCursor(raw, rate_hz=RATE_HZ, chunk_bytes=1 << 15, start=mark)
    assert late.position == state.last_index + 1 <= spans[1][0] < n_total
    t, f = window_on_disk(late, *spans[1], tmp_path / "late")
    assert np.array_equal(t[0:t.size], on_disk[1].fog_t_s[0:t.size])
    assert np.array_equal(f[0:f.size], on_disk[1].fog_dps[0:f.size])
    with pytest.raises(ValueError, match="already passed"):
        next(late.window(0, 10))
    with pytest.raises(TypeError, match="chunks"):
        np.asarray(f)


def test_a_half_read_ahead_gives_the_first_look_made_without_it(
        demo_run: DemoRun, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The worker reads each half's FOG window as the half completes (read_half_ahead);
    the pair's first look then reads no window again and says exactly what it says
    when it reads them all itself. Two copies of the demo run: two worker readers."""
    plain_dir = demo_run.copy_to(tmp_path / "plain")
    ahead_dir = demo_run.copy_to(tmp_path / "ahead")
    cfg = load_config(plain_dir / "procedure.yaml", plain_dir / "stand.yaml")
    events = RunDir(plain_dir).events()
    first = HalfAcquired.all_in(events)[0]
    halves = unit_halves(events, first.unit, first.session)
    static = static_record(events, first.axis)
    rate = abs(first.set_rate_dps)
    try:
        plain = pair_summary(str(plain_dir), cfg, first.axis, rate, halves, static)
        for h in halves:
            read_half_ahead(str(ahead_dir), cfg, h, static)
        reads: list[Path] = []

        def counted(cursor: CaptureCursor, i_from: int, i_to: int, stem: Path,
                    span: object = None) -> tuple[DiskArray, DiskArray]:
            reads.append(stem)
            return window_on_disk(cursor, i_from, i_to, stem, span)  # type: ignore[arg-type]
        monkeypatch.setattr(ladder_analysis, "window_on_disk", counted)
        ahead = pair_summary(str(ahead_dir), cfg, first.axis, rate, halves, static)
    finally:
        for d in (plain_dir, ahead_dir):
            raw = ladder_analysis._WORKER_READERS.pop(str(d), None)
            if raw is not None:
                raw.close()
    assert len(halves) >= 2 and reads == []          # every window was read ahead
    assert ahead.summary == plain.summary
    assert ahead.key == plain.key and ahead.temperatures.keys() == plain.temperatures.keys()
