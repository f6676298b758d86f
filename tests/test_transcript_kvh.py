"""KVH FOG/IMU: the manual's sample frame, its configuration dialogue, and the twin.

Sources: KVH 1775 IMU Technical Manual 54-0938 with ICD 56-0298 Rev. B.
- Table 5-1/5-2 (p. 14): format A, 36 bytes, header 0xFE81FF55, rotational data "Radians
  or degrees, selectable; delta angle or rate of rotation, selectable".
- 5.2.1 "Sample Output" and Table 5-10 (p. 18): the frame below, with Gyro X/Y/Z
  2.019593E-5, 5.159911E-5, -1.3111248E-5 in "Configuration dependent (default: delta
  radians)".
- Section 7 (p. 24-25): a command `=NAME,args` answers `NAME,args`; a query `?NAME`
  answers `NAME,value`; an unknown word in Configuration Mode answers `INVALID,...`.
- 8.8/8.9 (p. 33): `=DR,<rate>` answers `DR,<rate>`; `?DR` answers `DR,<rate>`.
- 8.20 (p. 44): `?IS` "returns the main serial number of the unit": `IS,[Serial Number]`,
  "a text string, typically with a numeric value" (issue 41: the twin answered INVALID).
The words CONFIG, ROTFMT, ROTUNITS and OUTPUTFMT are not in the pages we could read
(drivers/kvh_config.py says so); the dialogue below follows section 7's conventions.
"""

from __future__ import annotations

import contextlib
import math
import time
from pathlib import Path

import numpy as np
import pytest
import serial

from drivers.fog import Fog, FogError, dps_per_unit, read_capture
from drivers.fog_formats import decode
from drivers.fog_settings import FogSettings
from drivers.kvh_config import WORDS, KvhConfigError, KvhConfigurator, KvhTarget
from drivers.transport import TranscriptTransport
from sims.clock import VirtualClock
from sims.fog_twin import FogTwin
from sims.stand import AxisTruth, FogTruth, SimulatedStand, StandTruth

pytestmark = pytest.mark.timeout(30)

#: 5.2.1 "Sample Output" (p. 18), as printed
SAMPLE = ("FE 81 FF 55 37 A9 6A 6E 38 58 6C 1F B7 5B F8 62 BF 80 3E 78 BB 65 0D 28 3B 0A "
          "37 AC 77 3D 00 28 4B FA 34 D8")

SET_DEG_S = [
    ("=CONFIG,1", "CONFIG,1"),
    ("=OUTPUTFMT,A", "OUTPUTFMT,A"), ("=ROTFMT,RATE", "ROTFMT,RATE"),
    ("=ROTUNITS,DEG", "ROTUNITS,DEG"), ("=DR,1000", "DR,1000"),
    ("?OUTPUTFMT", "OUTPUTFMT,A"), ("?ROTFMT", "ROTFMT,RATE"),
    ("?ROTUNITS", "ROTUNITS,DEG"), ("?DR", "DR,1000"),
    ("?IS", "IS,0"),           # 8.20: its serial (a unit with none set answers 0)
    ("=CONFIG,0", "CONFIG,0"),
]
#: 8.20: the serial number query, in Configuration Mode
IDENTIFY = [("=CONFIG,1", "CONFIG,1"), ("?IS", "IS,0"), ("=CONFIG,0", "CONFIG,0")]
#: a unit at its power-on default, only read back
VERIFY_AT_POWER_ON = [
    ("=CONFIG,1", "CONFIG,1"),
    ("?OUTPUTFMT", "OUTPUTFMT,A"), ("?ROTFMT", "ROTFMT,DELTA"),
    ("?ROTUNITS", "ROTUNITS,RAD"), ("?DR", "DR,1000"),
    ("?IS", "IS,0"),
    ("=CONFIG,0", "CONFIG,0"),
]


def test_the_manuals_sample_frame_is_delta_radians():
    frames, _, stats = decode(bytes.fromhex(SAMPLE.replace(" ", "")), "kvh-a")
    assert stats.frames == 1 and stats.crc_errors == 0
    np.testing.assert_array_equal(frames.rates[0], np.float32([2.019593e-5, 5.159911e-5,
                                                               -1.3111248e-5]))
    assert int(frames.status[0]) == 0x77 and int(frames.temperature[0]) == 0x28
    # at 1000 Hz, 2.019593e-5 rad per sample is 1.1571 deg/s; read as deg/s, 57 296x less
    x_dps = float(frames.rates[0, 0]) * dps_per_unit("rad", 1000.0)
    assert x_dps == pytest.approx(2.019593e-5 * 1000 * 180 / math.pi, rel=1e-6)
    assert x_dps / float(frames.rates[0, 0]) == pytest.approx(57295.78, rel=1e-6)


def test_driver_sets_units_and_reads_them_back_as_the_icd_says():
    link = TranscriptTransport(SET_DEG_S, termination="\r\n")
    got = KvhConfigurator(link, port="ttyTEST").apply(KvhTarget("deg/s", 1000.0, "A", "set"))
    link.assert_done()
    assert got == {"fog.format": "A", "fog.units": "deg/s", "fog.rate_hz": "1000"}


def test_the_driver_reads_the_serial_with_its_settings():
    """8.20: the serial read in the same Configuration Mode session; the bench compares it
    with the stand's fog.serial (bench/core/traceability.py identity_mismatches)."""
    dialogue = [(sent, "IS,170912345" if sent == "?IS" else want)
                for sent, want in SET_DEG_S]
    link = TranscriptTransport(dialogue, termination="\r\n")
    got = KvhConfigurator(link, port="ttyTEST").apply(KvhTarget("deg/s", 1000.0, "A", "set"))
    link.assert_done()
    assert got["fog.serial"] == "170912345"


def test_verify_at_power_on_default_refuses_naming_the_stand_key():
    link = TranscriptTransport(VERIFY_AT_POWER_ON, termination="\r\n")
    with pytest.raises(KvhConfigError, match="fog.units: the stand says deg/s, the FOG "
                                             "outputs rad"):
        KvhConfigurator(link, port="ttyTEST").apply(KvhTarget("deg/s", 1000.0, "A",
                                                              "verify"))
    link.assert_done()


def test_the_serial_query_reads_the_icds_answer():
    link = TranscriptTransport([("?IS", "IS,170912345")], termination="\r\n")
    assert KvhConfigurator(link).query(WORDS.serial_number) == "170912345"
    link.assert_done()


def test_an_unknown_word_is_reported_by_name():
    link = TranscriptTransport([("=CONFIG,1", "CONFIG,1"), ("=OUTPUTFMT,A",
                                "INVALID,=OUTPUTFMT,A"), ("=CONFIG,0", "CONFIG,0")],
                               termination="\r\n")
    with pytest.raises(KvhConfigError, match="'=OUTPUTFMT,A' answered 'INVALID"):
        KvhConfigurator(link).apply(KvhTarget("deg/s", 1000.0, "A", "set"))


def fog_block(units: str, **kw: str) -> FogSettings:
    """A stand's `fog:` block for a twin (its port is the twin's own; the twin samples at
    the stand axis's rate): a FOG configured earlier to `units` (configure: declare)."""
    return FogSettings(port="", rate_hz=1000.0, units=units, **kw)  # type: ignore[arg-type]


@contextlib.contextmanager
def twin_at_power_on(speed: float = 100.0):
    clock = VirtualClock(speed, running=False)
    truth = FogTruth(scale=1.0003, bias_dps=0.002, noise_dps=0.01)
    stand = SimulatedStand(StandTruth(seed=3, axes={"outer": AxisTruth(fog=truth)}),
                           {"outer": 1000.0}, clock)
    twin = FogTwin(stand, "outer", keep_truth=True)   # units: the power-on default
    with twin:
        yield twin, stand, clock


def test_the_twin_answers_the_same_dialogues_on_its_pty():
    with twin_at_power_on() as (twin, _, _):
        assert twin.units == "rad"                   # Table 5-10: default delta radians
        with serial.Serial(twin.path, 921600, timeout=0.05) as ser:
            for sent, want in VERIFY_AT_POWER_ON + IDENTIFY + SET_DEG_S:
                ser.write((sent + "\r\n").encode())
                deadline = time.monotonic() + 2.0
                line = b""
                while not line.endswith(b"\n") and time.monotonic() < deadline:
                    line += ser.read(1)
                assert line.decode().strip() == want, sent
            ser.write(b"=ROTFMT,RATE\r\n")           # Normal Mode ignores input (ICD 7)
            time.sleep(0.1)
            assert ser.read(64) == b""
        assert twin.units == "deg/s"


def test_fog_set_at_connect_reads_true_rates_and_verify_refuses(tmp_path: Path):
    with twin_at_power_on() as (twin, stand, clock):
        with pytest.raises(FogError, match="fog.units: the stand says deg/s, the FOG "
                                           "outputs rad"):
            Fog(twin.path, rate_hz=1000, units="deg/s", configure="verify", raw_path=None,
                clock=clock).open()
        fog = Fog(twin.path, rate_hz=1000, units="deg/s", configure="set",
                  raw_path=tmp_path / "fog.raw", clock=clock)
        with fog:
            assert fog.readback["fog.units"] == "deg/s" and "set and read back" in \
                fog.identity()
            stand.axes["outer"].command_rate(0.0, 20.0, 50.0)  # the engine's order
            clock.start()
            fog.wait_for_index(2000, timeout_s=30.0)
            s = fog.samples(0, 2000)
        truth = twin.truth(0, 2000)
    np.testing.assert_allclose(s.rate_dps, truth.fog_dps.astype(np.float32), rtol=1e-6)
    assert abs(np.mean(s.rate_dps[500:]) - 20.0 * 1.0003 - 0.002) < 0.01
    _, dec = read_capture(tmp_path / "fog.raw", rate_hz=1000, units="deg/s")
    assert dec.skipped_bytes == 0 and dec.frames >= 2000   # no ASCII in the capture
