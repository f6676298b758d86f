"""The FOG driver against its twin, over a real pseudo-terminal.

Truth is the simulated stand's FOG output (float64) and what the twin put in each frame;
faults are injected by stand sample, so every expected count is known beforehand.
"""

from __future__ import annotations

import contextlib
import math
import os
import threading
import time
import tty
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import serial

import drivers.fog as fog_module
from bench.app.decode import decode_command
from drivers.fog import Fog, FogError, FogTimeout, read_capture
from drivers.fog_formats import StreamDecoder
from sims.clock import VirtualClock
from sims.fog_twin import Corrupt, Drop, FogTwin, Garbage, Stall
from sims.stand import AxisTruth, FogTruth, SimulatedStand, StandTruth
from tests.test_transcript_kvh import fog_block

pytestmark = pytest.mark.timeout(30)

FOG_TRUTH = FogTruth(scale=1.0003, bias_dps=0.002, misalignment_deg=0.2, noise_dps=0.01,
                     bias_drift_dps_per_h=0.001)


@contextlib.contextmanager
def rig(tmp_path: Path, *faults: object, rate_hz: float = 1000.0, speed: float = 100.0,
        units: str = "deg/s", axis_letter: str = "z", fmt: str = "kvh-a",
        rate_dps: float = 10.0) -> Iterator[tuple[Fog, FogTwin, SimulatedStand]]:
    """Stand (clock paused), twin, driver opened, then the clock started: the engine's order."""
    clock = VirtualClock(speed, running=False)
    stand = SimulatedStand(StandTruth(seed=7, axes={"outer": AxisTruth(fog=FOG_TRUTH)}),
                           {"outer": rate_hz}, clock)
    twin = FogTwin(stand, "outer", fog_block(units, format=fmt, axis=axis_letter),
                   keep_truth=True)
    twin.inject(*faults)  # type: ignore[arg-type]
    stand.axes["outer"].command_rate(0.0, rate_dps, 50.0)
    with twin:
        fog = Fog(twin.path, fmt=fmt, axis=axis_letter, rate_hz=rate_hz, units=units,
                  raw_path=tmp_path / "fog.raw", clock=clock, model="simulated DSP-1760")
        with fog:
            clock.start()
            yield fog, twin, stand


def wait(fog: Fog, i: int) -> None:
    fog.wait_for_index(i, timeout_s=i / fog.rate_hz + 5.0)


def test_rates_equal_truth_sample_for_sample(tmp_path: Path) -> None:
    n = 3000
    with rig(tmp_path) as (fog, twin, _):
        wait(fog, n)
        s = fog.samples(0, n)
        health = fog.health
    truth = twin.truth(0, n)
    assert np.array_equal(s.index, np.arange(n))
    assert np.array_equal(s.t_s, np.arange(n) / 1000.0)       # stand sample n at n / rate
    assert s.valid.all() and s.received.all()
    assert np.array_equal(s.rate_dps, truth.fog_dps.astype(np.float32).astype(np.float64))
    np.testing.assert_allclose(s.rate_dps, truth.fog_dps, rtol=1e-6, atol=1e-9)
    assert np.all(s.temperature == 25)
    assert health == "ok"


def test_faults_are_rejected_counted_and_placed(tmp_path: Path) -> None:
    faults = (Corrupt(200, count=2), Corrupt(400, byte=30, xor=0x80),   # temperature byte
              Drop(120 + 128 * 3, count=15),                              # across 127 -> 0
              Drop(900, count=1), Garbage(1500, 700, seed=3), Garbage(1700, 5, decoys=False))
    n = 2500
    with rig(tmp_path, *faults) as (fog, twin, _):
        wait(fog, n)
        s = fog.samples(0, n)
        stats = fog.stats
    truth = twin.truth(0, n)
    lost = [200, 201, 400, *range(504, 519), 900]
    assert np.flatnonzero(~s.received).tolist() == lost
    assert np.isnan(s.rate_dps[lost]).all()
    ok = s.received
    assert np.array_equal(s.rate_dps[ok], truth.rate_dps[ok])
    assert np.array_equal(ok, truth.intact)
    gaps = [(g.index, g.count) for g in stats.gap_events]
    assert gaps == [(200, 2), (400, 1), (504, 15), (900, 1)]
    assert stats.gap_events[2].t_s == pytest.approx(0.504)
    # corrupted frames: 3; the decoy headers inside the garbage burst fail their CRC too
    assert [e.index for e in stats.crc_events][:3] == [200, 201, 400]
    assert stats.crc_errors >= 3
    assert all(1500 <= e.index <= 1500 + 700 // 36 for e in stats.crc_events[3:])
    # back in sync within one frame: the frames right after each burst were decoded
    assert s.received[1500] and s.received[1700]
    assert fog.health == "degraded"


def test_raw_capture_decodes_to_exactly_the_live_samples(tmp_path: Path) -> None:
    faults = (Corrupt(150), Drop(333, 40), Garbage(700, 300, seed=1))
    with rig(tmp_path, *faults) as (fog, _, _):
        wait(fog, 1500)
    live_end = fog.end_index
    live = fog.samples(0, live_end)
    live_stats = fog.stats
    dec = StreamDecoder("kvh-a")
    raw = (tmp_path / "fog.raw").read_bytes()
    frames = [dec.feed(raw[i:i + 4096]) for i in range(0, len(raw), 4096)]
    index = np.concatenate([f.index for f in frames])
    z = np.concatenate([f.rates[:, 2] for f in frames]).astype(np.float64)
    assert index[-1] + 1 == live_end
    assert np.array_equal(index, np.flatnonzero(live.received))
    assert np.array_equal(z, live.rate_dps[live.received])
    assert (dec.frames, dec.crc_errors, dec.gaps, dec.lost_frames, dec.bytes) == (
        live_stats.frames, live_stats.crc_errors, live_stats.gaps, live_stats.lost_frames,
        live_stats.bytes)
    assert dec.crc_events == [(e.index, e.offset) for e in live_stats.crc_events]
    assert dec.gap_events == [(e.index, e.count) for e in live_stats.gap_events]
    # what `bench analyze` uses: the same samples, field for field
    again, _ = read_capture(tmp_path / "fog.raw", rate_hz=1000.0)
    for name in ("index", "t_s", "valid", "received"):
        assert np.array_equal(getattr(again, name), getattr(live, name)), name
    for name in ("rate_dps", "temperature"):
        assert np.array_equal(getattr(again, name), getattr(live, name), equal_nan=True), name


def test_bench_decode_prints_counts_and_writes_csv(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    with rig(tmp_path, Corrupt(50), Drop(100, 3)) as (fog, twin, _):
        wait(fog, 400)
    truth = twin.truth()
    n_frames = fog.stats.frames
    rc = decode_command(str(tmp_path / "fog.raw"), "kvh-a", str(tmp_path / "fog.csv"))
    out = capsys.readouterr().out.splitlines()
    assert rc == 1                                    # decoded, but frames were lost
    assert f"frames: {n_frames}" in out
    assert "crc_errors: 1" in out and "gaps: 2" in out and "lost_frames: 4" in out
    rows = (tmp_path / "fog.csv").read_text().splitlines()
    header = rows[0].split(",")
    assert header[:7] == ["index", "sequence", "status", "x", "y", "z", "temperature"]
    table = np.array([r.split(",") for r in rows[1:]], dtype=float)
    idx = table[:, 0].astype(int)
    assert len(idx) == n_frames
    assert np.array_equal(table[:, 1], idx % 128)
    assert np.all(table[:, 2] == 0x77)
    assert np.array_equal(table[:, 5].astype(np.float32), truth.value[idx])
    # the cross-axis channel carries the FOG's noise (about 0.01 deg/s), not exactly 0;
    # the temperature warms from 25 degC slowly (whole degrees)
    assert np.all(np.abs(table[:, 3]) < 0.1) and np.any(table[:, 3] != 0)
    assert np.all(table[:, 6] == 25)


def test_bench_decode_invalid_input(tmp_path: Path) -> None:
    assert decode_command(str(tmp_path / "missing.raw"), "kvh-a", None) == 2
    (tmp_path / "x.raw").write_bytes(b"")
    assert decode_command(str(tmp_path / "x.raw"), "nope", None) == 2
    assert decode_command(str(tmp_path / "x.raw"), "kvh-a", None) == 1  # no frame (CONTRACT)


@pytest.mark.parametrize(("units", "axis_letter"), [("rad/s", "x"), ("deg", "y"), ("rad", "z")])
def test_units_and_axis_from_config(tmp_path: Path, units: str, axis_letter: str) -> None:
    with rig(tmp_path, units=units, axis_letter=axis_letter, rate_hz=500.0) as (fog, twin, _):
        wait(fog, 800)
        s = fog.samples(0, 800)
    truth = twin.truth(0, 800)
    # a float32 in the frame carries ~7 digits of the stand's rate, whatever the units
    np.testing.assert_allclose(s.rate_dps, truth.fog_dps, rtol=2e-7, atol=1e-9)
    assert np.array_equal(s.rate_dps, truth.rate_dps)


def test_lossless_stall_times_out_then_catches_up(tmp_path: Path) -> None:
    # 100 s of silence at speed 50 is 2 s real. The timeout comes 0.27 s after the wait
    # starts plus 0.25 s of silence (0.52 s); the slack of ~1.5 s is for a loaded machine,
    # where the suite beside two busy processes once saw the stall (then 0.6 s) end first
    with rig(tmp_path, Stall(500, 100.0), speed=50.0) as (fog, _, _):
        fog.wait_margin_s = 0.25  # shorter than the bench's minimum, to see the timeout soon
        with pytest.raises(FogTimeout, match="sample 2000"):
            fog.wait_for_index(2000, timeout_s=1.0)
        wait(fog, 102_000)
        s = fog.samples(0, 102_000)
        stats = fog.stats
    assert s.received.all() and stats.lost_frames == 0 and stats.crc_errors == 0
    assert len(stats.stalls) == 1
    stall = stats.stalls[0]
    assert stall.after_index == 499
    # the silence starts at sample 500 (0.5 s) and the twin sends again at 100.5 s; the
    # driver notices the silence when its reader next runs (late on a loaded machine: CI
    # saw 13.8 s), so the start may be late, never early, and the end is the resumption
    assert 0.5 <= stall.t_from_s < 100.5
    assert 100.5 - 1e-6 <= stall.t_from_s + stall.duration_s <= 100.5 + 15.0  # 0.3 s real
    assert fog.last_error is None


def test_loss_of_whole_counter_wraps_is_flagged(tmp_path: Path) -> None:
    """200 frames lost in one silence: the counter shows 72; the clock shows the rest."""
    with rig(tmp_path, Stall(200, 1.0, lose=True), rate_hz=200.0, speed=5.0) as (fog, _, _):
        wait(fog, 1100)
        deadline = time.monotonic() + 3.0
        while fog.health != "error" and time.monotonic() < deadline:
            time.sleep(0.05)
        stats = fog.stats
        err = fog.last_error
    assert [(g.index, g.count) for g in stats.gap_events] == [(200, 72)]
    assert err is not None and "whole counter wraps" in err and "after 199" in err
    assert stats.index_uncertain_from == 200


def test_wait_timeout_is_scaled_by_clock_speed(tmp_path: Path) -> None:
    clock = VirtualClock(100.0, running=False)  # never started: no frame ever comes
    stand = SimulatedStand(StandTruth(seed=1, axes={"outer": AxisTruth()}), {"outer": 1000}, clock)
    with FogTwin(stand, "outer") as twin, Fog(twin.path, rate_hz=1000, raw_path=None,
                                              clock=clock, units="rad",
                                              wait_margin_s=0.25) as fog:
        t0 = time.monotonic()
        with pytest.raises(FogTimeout, match="sample 0 .* within 50 s"):
            fog.wait_for_index(0, timeout_s=50.0)      # 0.5 s real + margin
        assert 0.5 <= time.monotonic() - t0 < 2.0
        assert fog.health == "ok" and fog.stats.frames == 0


def test_samples_range_checks_and_discard(tmp_path: Path) -> None:
    with rig(tmp_path) as (fog, _, _):
        wait(fog, 1000)
        fog.discard_before(600)
        with pytest.raises(ValueError, match="before 600 were discarded"):
            fog.samples(599, 700)
        assert fog.samples(600, 700).index[0] == 600
        with pytest.raises(ValueError, match="wait_for_index first"):
            fog.samples(600, 10**9)


def test_identity_and_open_errors(tmp_path: Path) -> None:
    clock = VirtualClock(1.0)
    fog = Fog("/dev/does-not-exist", rate_hz=1000, raw_path=None, clock=clock,
              model="KVH DSP-1760", units="rad")
    assert "KVH DSP-1760" in fog.identity() and "kvh-a" in fog.identity()
    with pytest.raises(FogError, match="/dev/does-not-exist"):
        fog.open()
    (tmp_path / "file").write_text("")
    clock2 = VirtualClock(100.0, running=False)
    stand = SimulatedStand(StandTruth(seed=1, axes={"outer": AxisTruth()}), {"outer": 1000},
                           clock2)
    with FogTwin(stand, "outer") as twin:
        bad = Fog(twin.path, rate_hz=1000, raw_path=tmp_path / "file" / "fog.raw", clock=clock2,
                  units="rad")
        with pytest.raises(FogError, match="raw capture"):
            bad.open()
        with Fog(twin.path, rate_hz=1000, raw_path=None, clock=clock2, units="rad") as again:
            assert again.health == "ok"            # the failed open let go of the port
    with pytest.raises(ValueError, match="units 'g'"):
        Fog("p", rate_hz=1000, raw_path=None, clock=clock, units="g")
    with pytest.raises(ValueError, match="axis 'w'"):
        Fog("p", rate_hz=1000, raw_path=None, clock=clock, axis="w", units="rad")
    with pytest.raises(ValueError, match="unknown FOG frame format"):
        Fog("p", rate_hz=1000, raw_path=None, clock=clock, fmt="nope", units="rad")
    with pytest.raises(FogError, match="names no fog.units.*delta radians"):
        Fog("p", rate_hz=1000, raw_path=None, clock=clock, units=None)


def test_twin_refuses_a_stand_already_running() -> None:
    clock = VirtualClock(100.0)
    stand = SimulatedStand(StandTruth(seed=1, axes={"outer": AxisTruth()}), {"outer": 1000}, clock)
    stand.advance()
    with pytest.raises(RuntimeError, match="before anything advances the axis"):
        FogTwin(stand, "outer")


def test_kvh_b_over_the_pty(tmp_path: Path) -> None:
    with rig(tmp_path, fmt="kvh-b") as (fog, twin, _):
        wait(fog, 500)
        s = fog.samples(0, 500)
    assert np.array_equal(s.rate_dps, twin.truth(0, 500).rate_dps)
    assert not math.isnan(s.rate_dps.sum())


@contextlib.contextmanager
def _pty_port() -> Iterator[tuple[int, serial.Serial]]:
    """A pty's master (what a twin writes) and its slave as the driver opens it."""
    master, slave = os.openpty()
    tty.setraw(slave)
    port = serial.Serial(os.ttyname(slave), 921600, timeout=0.05)
    os.close(slave)
    try:
        yield master, port
    finally:
        port.close()
        os.close(master)


def _write_later(master: int, data: bytes, after_s: float) -> threading.Thread:
    def write() -> None:
        time.sleep(after_s)
        os.write(master, data)
    t = threading.Thread(target=write, daemon=True)
    t.start()
    return t


def test_a_batch_waits_for_the_bytes_a_stepped_twin_has_sent(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """On a stepped clock the batch holds the whole burst the twin has sent (`coming`),
    even where the pty runs empty in between; elsewhere it ends at the first empty
    moment, and a twin that counted bytes it never wrote holds it only for the cap."""
    piece = bytes(range(256)) * 16                          # 4 kB, one read's worth
    monkeypatch.setattr(fog_module, "_IN_FLIGHT_REAL_S", 10.0)  # ample on a loaded machine
    with _pty_port() as (master, port):
        os.write(master, piece)
        late = _write_later(master, piece[::-1], after_s=0.2)
        first = port.read(len(piece))
        got = Fog._batch(port, first, buf=bytearray(1 << 16), coming=lambda: 2 * len(piece))
        assert bytes(got) == piece + piece[::-1]            # waited for the late piece
        late.join()

        os.write(master, piece)
        late = _write_later(master, piece[::-1], after_s=0.2)
        alone = Fog._batch(port, port.read(len(piece)), buf=bytearray(1 << 16))
        assert bytes(alone) == piece                        # no twin says more is coming
        late.join()
        assert port.read(len(piece)) == piece[::-1]

        monkeypatch.setattr(fog_module, "_IN_FLIGHT_REAL_S", 0.3)
        os.write(master, piece)
        t0 = time.monotonic()
        short = Fog._batch(port, port.read(len(piece)), buf=bytearray(1 << 16),
                           coming=lambda: 3 * len(piece))   # more than will ever come
        assert bytes(short) == piece
        assert 0.3 <= time.monotonic() - t0 < 5.0


def test_a_fog_opened_while_the_clock_ran_starts_at_the_clock(tmp_path: Path) -> None:
    """The rate ladder opens an axis's FOG for that axis's units only. Its twin sends
    nothing while no reader has the port (a FOG streaming into a cable nobody listens
    to), and the driver places the first frame by the clock: opened at t = 12.3456 s,
    the capture starts at stand sample floor(12345.6) + 1 = 12346, by hand, and equals the
    twin's truth from there, live and decoded again from the raw file."""
    from sims.clock import SteppedClock

    clock = SteppedClock()
    stand = SimulatedStand(StandTruth(seed=7, axes={"outer": AxisTruth(fog=FOG_TRUTH)}),
                           {"outer": 1000.0}, clock)
    twin = FogTwin(stand, "outer", fog_block("deg/s"), keep_truth=True)
    stand.axes["outer"].command_rate(0.0, 10.0, 50.0)
    n = 3000
    with twin:
        clock.sleep(12.3456)      # 12 346 samples, 96 wraps of the counter, nobody reads
        assert twin.bytes_written == 0 and twin.frames_encoded == 0
        raw = tmp_path / "fog.raw"
        with Fog(twin.path, rate_hz=1000.0, units="deg/s", raw_path=raw, clock=clock) as fog:
            first = fog.first_index
            assert first == 12346 and fog.end_index == 12346
            fog.wait_for_index(first + n, timeout_s=10.0)
            s = fog.samples(first, first + n)
            stats = fog.stats
        clock.sleep(5.0)          # closed again: the frames go nowhere, the queue stays empty
        assert twin.frames_encoded == fog.stats.frames
    truth = twin.truth(first, first + n)
    assert not twin.truth(0, first).sent.any()
    assert np.array_equal(s.index, truth.index) and s.valid.all()
    assert np.array_equal(s.rate_dps, truth.fog_dps.astype(np.float32).astype(np.float64))
    assert stats.gaps == 0 and stats.lost_frames == 0 and stats.crc_errors == 0
    again, dec = read_capture(raw, rate_hz=1000.0, units="deg/s", first_index=first)
    assert again.index[0] == first and dec.lost_frames == 0
    assert np.array_equal(again.rate_dps[:n], s.rate_dps)
    assert np.array_equal(again.index[:n], s.index)


def test_a_reply_cut_by_the_read_deadline_is_read_whole_next_time() -> None:
    """A loaded machine delivered '=ROTFMT,RATE's answer across a read's deadline: the two
    halves matched neither and the run aborted ("no answer starting 'ROTFMT,RATE'")."""
    import os
    import threading

    import serial as pyserial

    from drivers.fog import _SerialLines

    master, slave = os.openpty()
    try:
        with pyserial.Serial(os.ttyname(slave), 921600, timeout=0.01) as ser:
            link = _SerialLines(ser)
            os.write(master, b"ROTF")
            later = threading.Timer(0.3, lambda: os.write(master, b"MT,RATE\r\n"))
            later.start()
            assert link.read(0.1) == b""            # the deadline falls inside the line
            later.join()
            assert link.read(1.0) == b"ROTFMT,RATE"
    finally:
        os.close(master)
        os.close(slave)
