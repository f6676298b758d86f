"""Keysight 53230A timestamps: the driver against the manual's text, and the twin too.

Sources (cited per exchange below):
- 53220A/53230A Programmer's Reference (Keysight), MEASure:ARRay:TSTamp? p. 240: "returns
  the prescaler value followed by a comma, followed by the measurements";
  SENSe:TSTamp:RATE p. 377: *RST sets 1.0E6; query form `+1.00000000E+006`; typical
  response `+13,+1.29383828200000E-006,+1.29352315400000E-006,...`;
  SYSTem:TIMeout p. 459: per measurement, non-volatile, query form `+2.00000000E+000`.
- 53220A/53230A User's Guide, "Time stamp" (p. 88-89 Agilent edition): "count+1 elements
  are actually returned"; each time stamp value is "the signal period itself (scale
  factor = 1 ...) or the signal period multiplied by the scale factor" -- an interval.

The transcript is a once-per-revolution zero mark (scale factor 1) at ~1 s a turn. The
decode the driver had before this test (values taken as edge times, refused unless they
increase) fails it: intervals of ~1 s do not increase, and taken as times they would
put every edge within 1.001 s of the start instead of up to 4 s after it.
"""

from __future__ import annotations

import numpy as np
import pytest

from drivers.counter import Counter, CounterReplyError
from drivers.counter_profiles import KEYSIGHT_53230A
from drivers.time_tie import TimeTie
from drivers.transport import Exchange, Like, expected_protocol
from sims.clock import VirtualClock
from sims.counter_twin import CounterTwin, SyncLink
from sims.truth import AxisTruth
from tests.counter_rig import AXIS, counter_block, truth_edges, turning_stand
from tests.transcripts import NO_ERROR_KEYSIGHT, NR3_KEYSIGHT, checked, replay_on_twin

IDN = "Keysight Technologies,53230A,MY50001234,02.05-1519.666-1.19-4.15-127-155-35"
#: the intervals of the reply: a zero mark every ~1 s (scale factor 1: period itself)
INTERVALS = ["+2.53417730000000E-001", "+9.99980387740000E-001",
             "+1.00001826240000E-000", "+9.99991151560000E-001"]
T0 = 100.0  # the host clock (paused) where INIT is sent: the host-clock tie's start


def open_and_identify() -> list[Exchange]:
    return [
        ("ABOR", None), ("*CLS", None), ("*OPC?", "1"),         # recover(): a known idle
        ("SYST:ERR?", NO_ERROR_KEYSIGHT),                        # drain the queue
        ("*IDN?", IDN),
        ("SYST:TIM?", "+1.00000000E+000"),   # p. 459: noted, so it can be restored
    ]


def input_setup() -> list[Exchange]:
    return [
        *checked("INP1:COUP DC"), *checked("INP1:IMP 1000000"),
        *checked("INP1:LEV:AUTO OFF"), *checked("INP1:LEV 2.5"), *checked("INP1:SLOP POS"),
    ]


def input_readback() -> list[Exchange]:
    return [("INP1:COUP?", "DC"), ("INP1:IMP?", "+1.00000000E+006"),
            ("INP1:LEV:AUTO?", "0"), ("INP1:LEV?", "+2.50000000E+000"),
            ("INP1:SLOP?", "POS")]


def arm_timestamps(count: int, source: str = "IMM") -> list[Exchange]:
    return [
        *checked("ABOR"),
        *checked(f"CONF:ARR:TST ({count}),(@1)"),                # p. 240: parentheses
        *input_setup(),
        *checked("FORM ASCii"),
        *checked("TST:RATE 10000"), ("TST:RATE?", "+1.00000000E+004"),   # p. 377
        *checked("TRIG:SOUR " + source), ("TRIG:SOUR?", source),
        *checked("SYST:TIM 2.5"),            # per reading: a start edge and one turn
        *checked("INIT"), ("*OPC", None),
    ]


def transcript() -> list[Exchange]:
    return [
        *open_and_identify(),
        *input_setup(), *input_readback(),
        *arm_timestamps(4),
        ("*ESR?", "+1"),                       # operation complete
        ("FETC?", "+1," + ",".join(INTERVALS)),  # prescaler, then count intervals
        ("SYST:ERR?", NO_ERROR_KEYSIGHT),
        *checked("SYST:TIM +1.00000000E+000"),   # restored at close (non-volatile)
    ]


def make_counter(transport, tie: TimeTie | None = None) -> Counter:
    clock = VirtualClock(1000.0, start_s=T0, running=False)   # paused: INIT at T0 exactly
    return Counter.open("TCPIP0::192.0.2.1::5025::SOCKET", KEYSIGHT_53230A, clock,
                        transport=transport, time_tie=tie, timeout_margin_s=0.5)


def test_timestamps_are_intervals_decoded_to_edges():
    with expected_protocol(make_counter, transcript()) as counter:
        counter.configure(channel=1, level_v=2.5, slope="POS", coupling="DC",
                          impedance_ohm=1e6)
        edges = counter.acquire_edges(4, 1.0)
        counter.close()
    intervals = np.array([float(v) for v in INTERVALS])
    np.testing.assert_allclose(edges, T0 + np.cumsum(intervals), rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.diff(edges), intervals[1:], rtol=0, atol=1e-12)
    assert counter.readback["counter.level_v"] == "+2.50000000E+000"
    assert counter.readback["counter.timestamp_rate_hz"] == "+1.00000000E+004"


def test_the_manuals_typical_response_is_refused_for_its_prescaler():
    """p. 377's typical response: prescaler 13, so only every 13th edge was stamped."""
    reply = "+13,+1.29383828200000E-006,+1.29352315400000E-006"
    exchanges = [*open_and_identify(), *input_setup(), *input_readback(),
                 *arm_timestamps(2), ("*ESR?", "+1"), ("FETC?", reply),
                 # the failure is recovered from: ABOR, *CLS, *OPC? (then closed)
                 ("ABOR", None), ("*CLS", None), ("*OPC?", "1"),
                 *checked("SYST:TIM +1.00000000E+000")]
    with expected_protocol(make_counter, exchanges) as counter:
        counter.configure(channel=1, level_v=2.5, slope="POS", coupling="DC",
                          impedance_ohm=1e6)
        with pytest.raises(CounterReplyError, match="prescaler 13"):
            counter.acquire_edges(2, 1.0)
        counter.close()


def test_a_readback_that_differs_refuses_by_stand_key():
    exchanges = [*open_and_identify(), *input_setup(),
                 ("INP1:COUP?", "DC"), ("INP1:IMP?", "+5.00000000E+001"),
                 ("ABOR", None), ("*CLS", None), ("*OPC?", "1"),
                 *checked("SYST:TIM +1.00000000E+000")]
    with expected_protocol(make_counter, exchanges) as counter:
        with pytest.raises(Exception, match=r"counter.impedance_ohm: set 1000000.0, the "
                                            r"counter reads back '\+5.00000000E\+001'"):
            counter.configure(channel=1, level_v=2.5, slope="POS", coupling="DC",
                              impedance_ohm=1e6)
        counter.close()


def test_the_twin_answers_the_same_transcript():
    """The same lines over TCP to the twin: the manual's replies, the twin's numbers."""
    stand = turning_stand()
    twin = CounterTwin(stand, AXIS, counter_block("keysight-53230a"),
                       sync=SyncLink(period_s=2.0, latency_s=3e-6), timeout_s=1.0)
    data = Like("+1," + ",".join(INTERVALS), r"\+1(," + NR3_KEYSIGHT + "){4}")
    lines = [(s, Like(r, r".+") if s == "*IDN?" else (data if s == "FETC?" else r))
             for s, r in transcript() if s != "*ESR?"]
    # *RST leaves SYST:TIM (non-volatile, p. 459); TST:RATE returns to 1E6 (p. 377)
    lines = [("*RST", None), ("TST:RATE?", "+1.00000000E+006"),
             ("SYST:TIM?", "+1.00000000E+000"), *lines]
    with twin:
        stand.clock.start()
        got = replay_on_twin(twin.start(), lines)
        acq = twin.last_acquisition
    values = np.array([float(v) for v in got[-3].split(",")])
    truth = truth_edges(stand, acq.t_start_s, acq.t_start_s + 5.0)[:4]
    # the twin's intervals are the stand's: first from the start event, then turn periods
    np.testing.assert_allclose(np.cumsum(values[1:]) + acq.t_start_s, truth, rtol=0,
                               atol=KEYSIGHT_53230A.resolution_s)


def test_an_external_reference_is_set_checked_and_read_back():
    """User's Guide 'Time base' (p. 69 Agilent / p. 81 Keysight edition): SENS:ROSC:SOUR
    EXT, SENS:ROSC:EXT:CHEC ONCE, SYST:ERR? (an error if no valid signal)."""
    exchanges = [*open_and_identify(),
                 *checked("ROSC:SOUR EXT"), *checked("ROSC:EXT:CHEC ONCE"),
                 ("ROSC:SOUR?", "EXT"),
                 *checked("SYST:TIM +1.00000000E+000")]
    with expected_protocol(make_counter, exchanges) as counter:
        assert counter.verify_reference("external", 1e-9) == "EXT"
        counter.close()
    assert counter.readback["counter.reference"] == "EXT"


def test_a_timebase_claim_on_the_internal_reference_is_refused():
    exchanges = [*open_and_identify(), ("ROSC:SOUR?", "INT"),
                 *checked("SYST:TIM +1.00000000E+000")]
    with expected_protocol(make_counter, exchanges) as counter:
        with pytest.raises(Exception, match="counter.timebase_limit_rel = 1e-09 assumes an "
                                            "external reference, but the counter runs on "
                                            "'INT'"):
            counter.verify_reference(None, 1e-9)
        counter.close()


def test_the_twin_refuses_the_check_without_a_reference_signal():
    stand = turning_stand()
    twin = CounterTwin(stand, AXIS, counter_block("keysight-53230a"),
                       AxisTruth(counter_external_reference=False))
    with twin:
        replay_on_twin(twin.start(), [
            ("ROSC:SOUR EXT", None), ("SYST:ERR?", NO_ERROR_KEYSIGHT),
            ("ROSC:EXT:CHEC ONCE", None), ("SYST:ERR?", Like("", r"-241,.*")),
            ("ROSC:SOUR?", "EXT")])


def test_fog_sync_tie_places_the_edges_after_the_next_sync_pulse():
    """TRIG:SOUR EXT from the FOG's sync output (every 5 s of FOG time, 2 us of link):
    INIT at host time 100.0 -> the start event is the pulse at 105 s + 2 us, and the
    manual's intervals run from there (drivers/time_tie.py)."""
    tie = TimeTie("fog-sync", sync_period_s=5.0, latency_s=2e-6, latency_u_s=2e-7)
    exchanges = [*open_and_identify(), *input_setup(), *input_readback(),
                 *arm_timestamps(4, "EXT"), ("*ESR?", "+1"),
                 ("FETC?", "+1," + ",".join(INTERVALS)), ("SYST:ERR?", NO_ERROR_KEYSIGHT),
                 *checked("SYST:TIM +1.00000000E+000")]
    with expected_protocol(lambda t: make_counter(t, tie), exchanges) as counter:
        counter.configure(channel=1, level_v=2.5, slope="POS", coupling="DC",
                          impedance_ohm=1e6)
        edges = counter.acquire_edges(4, 1.0)
        acq = counter.last_acquisition
        counter.close()
    intervals = np.array([float(v) for v in INTERVALS])
    assert acq.t_start_s == pytest.approx(105.0 + 2e-6, abs=1e-12)
    assert acq.t_start_u_s == 2e-7
    np.testing.assert_allclose(edges, 105.0 + 2e-6 + np.cumsum(intervals), rtol=0,
                               atol=1e-12)
