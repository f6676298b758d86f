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
"""

from __future__ import annotations

import re
import time

import numpy as np
import pytest
import serial

from drivers.fog_formats import decode
from drivers.kvh_config import G0_MPS2
from tests.test_transcript_kvh import twin_at_power_on

pytestmark = pytest.mark.timeout(40)


def dialogue(ser: serial.Serial, sent: str) -> str:
    """Send one line, return its answer: `NAME,...` or `INVALID,...`. Binary frames still
    in the port's buffer (sent before Configuration Mode stopped them) are skipped, as a
    client does (drivers/kvh_config.py)."""
    name = sent[1:].split(",", 1)[0]
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
            np.testing.assert_allclose(frames.extra["az"], 1.0)     # +1 g, axis up
            np.testing.assert_allclose(frames.extra["ax"], 0.0)
            assert np.all(frames.status == 0x77)                      # valid, all six
            assert np.all(frames.temperature == 25)
            for sent, want in (("=CONFIG,1", "CONFIG,1"), ("=LINFMT,DELTA", "LINFMT,DELTA"),
                               ("=LINUNITS,FEET", "LINUNITS,FEET"),
                               ("=TEMPUNITS,F", "TEMPUNITS,F"),
                               ("=OUTPUTFMT,B", "OUTPUTFMT,B"), ("=CONFIG,0", "CONFIG,0")):
                assert dialogue(ser, sent) == want
            frames, _, _ = decode(capture(ser, clock, 2.0), "kvh-b")
            assert frames.extra["az"].size > 10
            # delta velocity over one 1000 Hz frame, in feet per second
            np.testing.assert_allclose(frames.extra["az"], G0_MPS2 / 1000 / 0.3048, rtol=1e-6)
            assert np.all(frames.temperature == 77)
            for sent, want in (("=CONFIG,1", "CONFIG,1"), ("=BAUD,460800", "BAUD,460800"),
                               ("=RSTCFG", "RSTCFG"), ("?OUTPUTFMT", "OUTPUTFMT,A"),
                               ("?LINFMT", "LINFMT,ACCEL"), ("?TEMPUNITS", "TEMPUNITS,C"),
                               ("?ROTFMT", "ROTFMT,DELTA"), ("?BAUD", "BAUD,460800"),
                               ("=CONFIG,0", "CONFIG,0")):
                assert dialogue(ser, sent) == want
