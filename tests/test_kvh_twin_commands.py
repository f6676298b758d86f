"""The KVH FOG twin as a user's own script configures it over the pty (issue 24).

Sources: KVH 1775 IMU Technical Manual 54-0938 / ICD 56-0298 Rev. B: =BAUD and ?BAUD
(8.3, 8.4, p. 30-31), ?LINUNITS -> LINUNITS,<METERS|FEET> "only meaningful if the
linear data output format is changed from the default value of acceleration in g's"
(8.24), ?FILTTYPE,<A|G> (8.17, the pattern of ?FILTEN), RSTCFG leaves the baud rate
(Table 9 note 1), "+1 G due to Earth gravity when its positive axis is up" (note 4),
=DR sets the data output rate (8.8, note 2), format A/B frames (Tables 5-1..5-4).
Before issue 24: =DR,100 was echoed while frames stayed at 1000 Hz, accelerations read
0 g, and TEMPUNITS, LINUNITS, LINFMT, FILTEN, BAUD, RSTCFG, OUTPUTFMT,B were INVALID.
The frames are decoded by the project's decoder, whose fields and CRC were checked
byte for byte against an independent decoder (issue 24's own report).

Issue 41 (the same manual): 3.3 / Table 3-1, in Configuration Mode "the unit will stop
output of binary data" and in Normal Mode it outputs "at the preconfigured rate" (the
twin sent the frames that fell due while configuring as a burst after it, ~2200 in the
first second); 8.20 (p. 44), `?IS` "returns the main serial number of the unit", response
`IS,[Serial Number]` (the twin answered INVALID); Table 5-2, the X/Y rotational data, the
accelerations and the temperature are the unit's measurements (the twin sent x = y = 0.0,
exactly 1 g and a constant 25).
"""

from __future__ import annotations

import re
import time

import numpy as np
import pytest
import serial

from drivers.fog import _SerialLines, dps_per_unit
from drivers.fog_formats import decode
from drivers.kvh_config import G0_MPS2, KvhConfigurator
from sims.clock import VirtualClock
from sims.fog_twin import ACCEL_NOISE_G, FogTwin
from sims.stand import (
    IMU_LEVEL_MEAN,
    IMU_LEVEL_STD,
    AxisChunk,
    AxisTruth,
    FogTruth,
    SimulatedStand,
    StandTruth,
)
from tests.test_transcript_kvh import fog_block, twin_at_power_on

pytestmark = pytest.mark.timeout(40)


def dialogue(ser: serial.Serial, sent: str) -> str:
    """Send one line, return its answer: `NAME,...` or `INVALID,...`. Binary frames still
    in the port's buffer (sent before Configuration Mode stopped them) are skipped, as a
    client does (drivers/kvh_config.py)."""
    name = sent[1:].split(",", 1)[0].upper()   # answers are upper case (ICD 7)
    answer = re.compile(rb"((?:" + re.escape(name.encode()) + rb"|INVALID)[ -~]*)\r\n")
    ser.write((sent + "\r\n").encode())
    deadline = time.monotonic() + 5.0
    data = b""
    while time.monotonic() < deadline:
        data += ser.read(65536)
        m = answer.search(data)
        if m:
            return m.group(1).decode("ascii")
    return ""


def capture(ser: serial.Serial, clock, seconds: float) -> bytes:  # noqa: ANN001
    """Bytes over `seconds` of stand time, from a clean frame boundary on."""
    ser.reset_input_buffer()
    t0 = clock.now()
    data = bytearray()
    while clock.now() < t0 + seconds:
        data += ser.read(65536)
    return bytes(data)


@pytest.mark.parametrize("units, combine", [("deg/s", "mean"), ("deg", "sum")])
def test_data_rate_changes_the_frame_rate(units: str, combine: str) -> None:
    with twin_at_power_on(speed=20.0) as (twin, stand, clock):
        with serial.Serial(twin.path, 921600, timeout=0.05) as ser:
            fmt, unit = {"deg/s": ("RATE", "DEG"), "deg": ("DELTA", "DEG")}[units]
            for sent, want in (("=CONFIG,1", "CONFIG,1"), (f"=ROTFMT,{fmt}", f"ROTFMT,{fmt}"),
                               (f"=ROTUNITS,{unit}", f"ROTUNITS,{unit}"),
                               ("=DR,100", "DR,100"), ("?DR", "DR,100"),
                               ("=DR,3600", "INVALID,=DR,3600"),   # beyond the stand's rate
                               ("=CONFIG,0", "CONFIG,0")):
                assert dialogue(ser, sent) == want
            clock.start()
            stand.axes["outer"].command_rate(clock.now(), 30.0, 1e6)
            frames, _, stats = decode(capture(ser, clock, 4.0), "kvh-a")
            # one frame per 10 stand samples (1000 Hz / 100 Hz), from sample 0 on
            samples, encoded = twin.next_sample, twin.frames_encoded
    assert stats.crc_errors == 0 and stats.frames > 50
    assert encoded == samples // 10
    seq = frames.sequence.astype(int)
    assert np.all(np.diff(seq) % 128 == 1)               # one count per frame
    z = frames.rates[:, 2].astype(float)
    moving = z[np.abs(z) > 0.5 * np.max(np.abs(z))]
    per_frame = 30.0 * 1.0003 if combine == "mean" else 30.0 * 1.0003 / 100.0  # deg per frame
    assert np.median(moving) == pytest.approx(per_frame, rel=2e-3)


def test_accelerometers_read_one_g_and_linear_and_temperature_settings() -> None:
    with twin_at_power_on(speed=20.0) as (twin, stand, clock):
        with serial.Serial(twin.path, 921600, timeout=0.05) as ser:
            for sent, want in (("=CONFIG,1", "CONFIG,1"), ("?LINFMT", "LINFMT,ACCEL"),
                               ("?LINUNITS", "LINUNITS,METERS"), ("?TEMPUNITS", "TEMPUNITS,C"),
                               ("?BAUD", "BAUD,921600"), ("?FILTEN,A", "FILTEN,A,1"),
                               ("=FILTEN,G,0", "FILTEN,G,0"), ("?FILTEN,G", "FILTEN,G,0"),
                               ("=BAUD,123", "INVALID,=BAUD,123"),
                               ("=CONFIG,0", "CONFIG,0")):
                assert dialogue(ser, sent) == want
            clock.start()
            frames, _, _ = decode(capture(ser, clock, 2.0), "kvh-a")
            assert frames.extra["az"].size > 10
            # +1 g, axis up, and 0 g across it, with the accelerometers' noise
            np.testing.assert_allclose(frames.extra["az"], 1.0, atol=10 * ACCEL_NOISE_G)
            np.testing.assert_allclose(frames.extra["ax"], 0.0, atol=10 * ACCEL_NOISE_G)
            assert np.all(frames.status == 0x77)                      # valid, all six
            assert np.all(frames.temperature == 25)   # whole degrees: 25.00x C so soon
            for sent, want in (("=CONFIG,1", "CONFIG,1"), ("=LINFMT,DELTA", "LINFMT,DELTA"),
                               ("=LINUNITS,FEET", "LINUNITS,FEET"),
                               ("=TEMPUNITS,F", "TEMPUNITS,F"),
                               ("=OUTPUTFMT,B", "OUTPUTFMT,B"), ("=CONFIG,0", "CONFIG,0")):
                assert dialogue(ser, sent) == want
            frames, _, _ = decode(capture(ser, clock, 2.0), "kvh-b")
            assert frames.extra["az"].size > 10
            # delta velocity over one 1000 Hz frame, in feet per second
            np.testing.assert_allclose(frames.extra["az"], G0_MPS2 / 1000 / 0.3048,
                                       rtol=10 * ACCEL_NOISE_G)
            assert np.all(frames.temperature == 77)
            for sent, want in (("=CONFIG,1", "CONFIG,1"), ("=BAUD,460800", "BAUD,460800"),
                               ("=RSTCFG", "RSTCFG"), ("?OUTPUTFMT", "OUTPUTFMT,A"),
                               ("?LINFMT", "LINFMT,ACCEL"), ("?TEMPUNITS", "TEMPUNITS,C"),
                               ("?ROTFMT", "ROTFMT,DELTA"), ("?BAUD", "BAUD,460800"),
                               ("=CONFIG,0", "CONFIG,0")):
                assert dialogue(ser, sent) == want


class _Recorder:
    """Everything the port gives, kept whole (frames and answers alike), as a raw
    capture holds it; `say` sends a line and reads on until its answer has come."""

    def __init__(self, ser: serial.Serial) -> None:
        self.ser = ser
        self.data = bytearray()

    def read_until(self, clock: VirtualClock, t_s: float) -> None:
        while clock.now() < t_s:
            self.data += self.ser.read(65536)

    def say(self, line: str, answer: str) -> tuple[int, int]:
        """Byte offsets where the answer starts and ends in `data`."""
        start = len(self.data)
        self.ser.write((line + "\r\n").encode())
        want = (answer + "\r\n").encode()
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            at = self.data.find(want, start)
            if at >= 0:
                return at, at + len(want)
            self.data += self.ser.read(65536)
        raise AssertionError(f"no {answer!r} to {line!r}")


def test_configuration_mode_sends_nothing_and_resumes_without_a_backlog() -> None:
    """ICD 3.3: no binary output in Configuration Mode, the configured rate after it. The
    frames that fell due meanwhile are never sent: the first frame after it is the one
    due then, its sequence counter where the time is, and the bench's decoder reads the
    capture across the session as one gap (drivers/fog_formats.py `gaps`)."""
    rate = 1000
    with twin_at_power_on(speed=20.0) as (twin, stand, clock):
        with serial.Serial(twin.path, 921600, timeout=0.05) as ser:
            rec = _Recorder(ser)
            time.sleep(0.1)
            stand.axes["outer"].command_rate(0.0, 30.0, 1e6)
            clock.start()
            rec.read_until(clock, 1.0)                            # streaming from sample 0
            t_in = clock.now()
            _, quiet_from = rec.say("=CONFIG,1", "CONFIG,1")
            t_in_done = clock.now()
            rec.read_until(clock, t_in_done + 2.0)                # two seconds configuring
            rec.say("?DR", "DR,1000")
            t_out = clock.now()
            quiet_to, resumed_at = rec.say("=CONFIG,0", "CONFIG,0")
            t0 = clock.now()
            rec.read_until(clock, t0 + 1.0)
            t1 = clock.now()
            truth = twin.truth()    # (once the port closes, what follows goes nowhere)
    data = bytes(rec.data)
    # nothing but the answers while configuring
    assert data[quiet_from:quiet_to] == b"DR,1000\r\n"
    # the first second after it carries that second's frames, not the ~2000 due before
    after, _, _ = decode(data[resumed_at:], "kvh-a")
    assert 0.5 * (t1 - t0) * rate < len(after) <= (t1 - t_out) * rate + 100
    # the samples not sent are one run, the session's; every other one went out
    unsent = truth.index[~truth.sent]
    lo, hi = int(unsent[0]), int(unsent[-1]) + 1
    assert np.array_equal(unsent, np.arange(lo, hi))
    assert t_in <= lo / rate <= t_in_done + 1 / rate
    assert t_out <= hi / rate <= t0 + 1 / rate and hi - lo >= 2.0 * rate
    # the whole capture: every frame sent, in order (but the last ones, still on their
    # way when the reading stopped), one gap where the session was
    frames, _, stats = decode(data, "kvh-a")
    sent = truth.index[truth.sent]
    assert stats.crc_errors == 0 and lo + len(after) <= len(frames) <= len(sent)
    sent = sent[:len(frames)]
    assert np.array_equal(frames.rates[:, 2].view(np.uint32),
                          truth.value[sent].view(np.uint32))
    assert np.array_equal(frames.sequence.astype(int), sent % 128)
    assert stats.gaps == 1 and int(stats.gap_index[0]) == lo
    assert int(stats.gap_count[0]) == ((hi - lo) % 128 or 128)  # the counter aliases


#: a pyserial port as a KvhConfigurator line link: the bench driver's own (the dialogue is
#: the ICD's either way; what is under test here is the twin's answer)
_Lines = _SerialLines


@pytest.mark.parametrize("serial_number, answer", [(None, "IS,0"),
                                                   ("170912345", "IS,170912345")])
def test_is_answers_the_serial_number(serial_number: str | None, answer: str) -> None:
    """ICD 8.20: `?IS` -> `IS,[Serial Number]` (in Configuration Mode; Normal Mode
    ignores it, section 7). The twin's serial is the stand file's fog.serial when the
    simulated bench passes it, "0" otherwise."""
    clock = VirtualClock(20.0, running=False)
    stand = SimulatedStand(StandTruth(seed=3, axes={"outer": AxisTruth()}), {"outer": 1000.0},
                           clock)
    block = None if serial_number is None else fog_block("rad", serial=serial_number)
    with FogTwin(stand, "outer", block) as twin, \
            serial.Serial(twin.path, 921600, timeout=0.05) as ser:
        ser.write(b"?IS\r\n")                  # Normal Mode: no answer
        time.sleep(0.2)
        assert ser.read(256) == b""
        assert dialogue(ser, "=CONFIG,1") == "CONFIG,1"
        assert dialogue(ser, "?IS") == answer
        assert dialogue(ser, "?is") == answer    # "Input commands are case-insensitive"
        # the project's own query client reads it as any NAME,value answer
        assert KvhConfigurator(_Lines(ser)).query("IS") == answer.split(",", 1)[1]
        assert dialogue(ser, "=CONFIG,0") == "CONFIG,0"
    with pytest.raises(ValueError, match="serial"):
        FogTwin(SimulatedStand(StandTruth(seed=3, axes={"outer": AxisTruth()}),
                               {"outer": 1000.0}, VirtualClock(1.0, running=False)),
                "outer", fog_block("rad", serial="12\r\n34"))


def _stand(clock: VirtualClock, noise_dps: float = 0.01) -> SimulatedStand:
    truth = FogTruth(scale=1.0003, bias_dps=0.002, noise_dps=noise_dps)
    return SimulatedStand(StandTruth(seed=5, axes={"outer": AxisTruth(fog=truth)}),
                          {"outer": 1000.0}, clock)


def test_other_channels_carry_the_stands_noise_and_leave_z_bit_for_bit() -> None:
    """Table 5-2: X and Y rotational data, accelerations and temperature are measured.
    The cross-axis gyros read white noise at the FOG's noise level (the earth rate's
    horizontal part left out), the accelerometers 1 g up and 0 g across with a little
    noise, the temperature whole degrees of a unit warming slowly. Their numbers are the
    stand's seeded grid's, from a stream of their own: the measured z channel is what a
    stand that never drew them gives, bit for bit."""
    clock = VirtualClock(20.0, running=False)
    stand = _stand(clock)
    twin = FogTwin(stand, "outer", fog_block("deg/s"))
    stand.axes["outer"].command_rate(0.0, 20.0, 50.0)
    with twin, serial.Serial(twin.path, 921600, timeout=0.05) as ser:
        time.sleep(0.1)
        clock.start()
        data = bytearray()
        deadline = time.monotonic() + 10.0
        while len(data) < 3000 * 36 and time.monotonic() < deadline:
            data += ser.read(65536)
    frames, _, stats = decode(bytes(data), "kvh-a")
    assert stats.crc_errors == 0 and stats.gaps == 0 and len(frames) >= 3000
    x, y = frames.rates[:, 0].astype(float), frames.rates[:, 1].astype(float)
    for cross in (x, y):
        assert abs(np.mean(cross)) < 0.002
        assert np.std(cross) == pytest.approx(0.01, rel=0.1)      # the FOG's noise level
    ax, ay, az = (frames.extra[k].astype(float) for k in ("ax", "ay", "az"))
    assert abs(np.mean(az) - 1.0) < 1e-4 and abs(np.mean(ax)) < 1e-4
    for a in (ax, ay, az):
        assert np.std(a) == pytest.approx(ACCEL_NOISE_G, rel=0.1)
    assert np.all(frames.temperature == 25)      # 25.00x C in the first seconds
    # z: bit for bit what a stand of the same seed gives without any twin drawing
    clock2 = VirtualClock(1.0, running=False)
    plain = _stand(clock2)
    got: list[AxisChunk] = []
    plain.axes["outer"].listeners.append(got.append)
    plain.axes["outer"].command_rate(0.0, 20.0, 50.0)
    plain.axes["outer"].advance_to(int(frames.index[-1]) / 1000.0)
    fog_dps = np.concatenate([c.fog_dps for c in got])
    want = (fog_dps / dps_per_unit("deg/s", 1000.0)).astype(np.float32)
    assert np.array_equal(frames.rates[:, 2].view(np.uint32),
                          want[frames.index].view(np.uint32))


def test_the_temperature_warms_slowly_and_the_draws_do_not_depend_on_chunks() -> None:
    """50 minutes on: the unit reads a degree warmer than its ambient. The other channels'
    draws are the stand's by sample (a chunk's start never changes a number), differ with
    the seed, and are standard deviates once scaled."""
    clock = VirtualClock(20.0, start_s=3000.0, running=False)
    stand = _stand(clock)
    twin = FogTwin(stand, "outer", fog_block("deg/s"))
    with twin:
        stand.advance()             # nobody reads yet: an hour of frames not sent
        with serial.Serial(twin.path, 921600, timeout=0.05) as ser:
            time.sleep(0.1)
            clock.start()
            frames, _, _ = decode(capture(ser, clock, 2.0), "kvh-a")
    assert len(frames) > 20 and np.all(frames.temperature == 26)   # 25 + 0.92 C
    axis = _stand(VirtualClock(1.0, running=False)).axes["outer"]
    whole, temp = axis.imu_levels(4000, 10000)
    parts = [axis.imu_levels(a, b - a) for a, b in ((4000, 4001), (4001, 9000),
                                                    (9000, 14000))]
    assert np.array_equal(whole, np.concatenate([p[0] for p in parts]))
    assert np.array_equal(temp, np.concatenate([p[1] for p in parts]))
    other = SimulatedStand(StandTruth(seed=6, axes={"outer": AxisTruth()}),
                           {"outer": 1000.0}, VirtualClock(1.0, running=False))
    assert not np.array_equal(whole, other.axes["outer"].imu_levels(4000, 10000)[0])
    deviates = (whole - IMU_LEVEL_MEAN) / IMU_LEVEL_STD       # standard deviates
    assert np.std(deviates) == pytest.approx(1.0, rel=0.02) and abs(np.mean(deviates)) < 0.02
