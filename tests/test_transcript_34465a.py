"""Keysight 34465A: the sample timer's measurement-dependent minimum, and Questionable
Data bit 2 (sample timing violation), as the manual says; the driver with no server and
the twin over TCP.

Sources: Keysight Truevolt Series Operating and Service Guide, SCPI Programming
Reference, SAMPle:TIMer (p. 309 in the manualslib copy): "The value of MIN is measurement
dependent. It depends on such things as the integration time, autozero on or off,
autorange on or off, and the measurement range ... Execute SAMPle:TIMer? MIN to determine
the recommended interval". From the same family's 34410A/11A User's Guide (SAMPle:TIMer
and STATus:QUEStionable, not found for the 34465A itself): "the MIN value is not
enforced, and you can specify an <interval> less than MIN (even zero)"; Questionable Data
bit 2, decimal 4, "Sample Timing Violation: A sample timing violation has occurred
involving the SAMPle:TIMer command. Sample timing may not be valid." The event register
is cleared when read.
"""

from __future__ import annotations

import pytest

from drivers.dmm import KEYSIGHT_34465A, Digitizer, DmmError
from drivers.transport import Like, expected_protocol
from sims.clock import VirtualClock
from tests.transcripts import NO_ERROR_KEYSIGHT, checked, replay_on_twin

IDN = "Keysight Technologies,34465A,MY59000001,A.03.01-03.15-03.01-00.52-03-02"


def configure(interval: str, minimum: str) -> list:
    return [
        *checked("ABOR"), *checked("CONF:VOLT 10"), *checked("VOLT:RANG 10"),
        *checked("VOLT:APER 0.0004"), *checked("VOLT:ZERO:AUTO OFF"),
        *checked("VOLT:IMP:AUTO ON"), *checked("TRIG:SOUR EXT"), *checked("TRIG:SLOP POS"),
        *checked("TRIG:DEL 0"), *checked("TRIG:COUN 1"), *checked("SAMP:SOUR TIM"),
        *checked(f"SAMP:TIM {interval}"), *checked("SAMP:COUN 4"), *checked("FORM ASC"),
        ("SAMP:TIM? MIN", minimum),            # measurement dependent: asked, not assumed
    ]


def opening() -> list:
    return [("ABOR", None), ("*CLS", None), ("*OPC?", "1"),
            ("SYST:ERR?", NO_ERROR_KEYSIGHT), ("*IDN?", IDN)]


def make(transport) -> Digitizer:
    return Digitizer.open("TCPIP0::192.0.2.7::5025::SOCKET", KEYSIGHT_34465A,
                          VirtualClock(1000.0, running=False), transport=transport,
                          timeout_margin_s=0.5)


def test_an_interval_below_the_minimum_is_refused_before_the_record():
    # 0.5 ms passes the driver's own floor (aperture + 10 us) but not what this DMM says
    # for this measurement (the MIN depends on range, autorange, resolution ...)
    exchanges = [*opening(), *configure("0.0005", "+6.00000000E-04"),
                 ("ABOR", None), ("*CLS", None), ("*OPC?", "1")]   # recovered, then closed
    with expected_protocol(make, exchanges) as dmm:
        with pytest.raises(DmmError, match=r"interval 0.0005 s is below SAMP:TIM\? MIN = "
                                           r"0.0006 s"):
            dmm.configure(10.0, 4e-4, 5e-4, 4)
        dmm.close()


def test_questionable_bit_2_after_the_record_refuses_its_samples():
    exchanges = [*opening(), *configure("0.0005", "+4.10000000E-04"),
                 ("STAT:QUES?", "+0"),                      # read-and-clear before
                 *checked("INIT"), ("*OPC", None), ("STAT:OPER:COND?", "+32"),
                 ("*ESR?", "+1"), ("FETC?", "+1.0E-01,+1.1E-01,+1.2E-01,+1.3E-01"),
                 ("STAT:QUES?", "+4"),                      # bit 2: sample timing violation
                 ("ABOR", None), ("*CLS", None), ("*OPC?", "1")]
    with expected_protocol(make, exchanges) as dmm:
        dmm.configure(10.0, 4e-4, 5e-4, 4)
        assert dmm.readback["dmm.sample_timer_min_s"] == pytest.approx(4.1e-4)
        dmm.arm()
        with pytest.raises(DmmError, match="bit 2 .sample timing violation"):
            dmm.fetch()
        dmm.close()


def test_the_twin_answers_min_and_sets_bit_2_as_the_manual_says():
    from sims.clock import VirtualClock as Clock
    from sims.gyro_rig import start_gyro_rig
    from sims.platform import GyroTruth, PlatformTruth
    from sims.stand import AxisTruth, SimulatedStand, StandTruth

    t = PlatformTruth(70.0, 80.0, {"x": GyroTruth(own_drift_dph=0.3, precession_dps_per_v=0.1,
                                                  k_as_v_per_deg=2.0)},
                      table_axis="turntable", seed=5)
    clock = Clock(50.0, running=False)
    stand = SimulatedStand(StandTruth(5, {"turntable": AxisTruth()}), {"turntable": 100.0},
                           clock)
    rig = start_gyro_rig(stand, t, {"x": 1})
    try:
        twin = rig.dmms["x"]
        lines = [("*RST", None), ("*CLS", None),
                 # after *RST: auto-zero ON, 10 PLC: a zero reading doubles each sample
                 ("SAMP:TIM? MIN", Like("", r"\+4\.0002\d*E-01")),
                 *[(s, r) for s, r in configure("0.0001", "") if s != "SAMP:TIM? MIN"],
                 ("SAMP:TIM? MIN", Like("", r"\+4\.10*E-04")),   # aperture 0.4 ms + 10 us
                 ("STAT:QUES?", "+0"), ("TRIG:SOUR IMM", None), ("INIT", None),
                 ("STAT:QUES?", "+4"), ("STAT:QUES?", "+0")]   # bit 2, then cleared
        replay_on_twin(twin.start(), lines)
    finally:
        rig.stop()
