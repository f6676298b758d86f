"""The CNT-91 twin against its handbook, where it once disagreed (issue 41).

Pendulum CNT-90 series Programmer's Handbook (and PyMeasure's cnt91 driver, an
independent client, pymeasure.instruments.pendulum.cnt91):
- :FORMat[:DATA] {ASCii|REAL}: REAL replies are IEEE 754 8-byte big-endian values in a
  definite-length block (PyMeasure's `format` property: FORM REAL, FORM? -> REAL);
- :MEASure:ARRay:TSTAmp? (<n>)[,(@ch)] and :CONFigure:ARRay:TSTAmp (the twin's reply
  layout, TS alone or X,TS pairs with FORM:TINF ON, is modelled on STSTamp's p. 8-72:
  unverified, see the profile's notes); :MEASure:ARRay:STSTamp? (p. 8-72);
- [:SENSe]:ROSCillator:SOURce {INTernal|EXTernal|AUTO} (unverified syntax, profile
  notes), so a CNT-91 stand can state `reference: internal|external`;
- :ARM:SOURce EXT4 (the rear arming input E): the FOG's sync pulse starts the time
  stamps, which is how the bench ties a CNT-91 to the FOG's time axis (fog-sync).
Before issue 41: FORM REAL was -224, MEAS:ARR:TSTA? and ROSC:SOUR were -113, and a
CNT-91 stand could state neither a reference nor a fog-sync time tie.
"""

from __future__ import annotations

import numpy as np
import pytest
from pymeasure.instruments.pendulum.cnt91 import CNT91

from drivers.counter import Counter, CounterCommandError, CounterError
from drivers.counter_profiles import PENDULUM_CNT91
from drivers.time_tie import TimeTie
from sims.counter_twin import SyncLink
from sims.truth import AxisTruth
from tests.conftest import Twins
from tests.counter_rig import AXIS, PERIOD_S, truth_edges, turning_stand
from tests.test_transcript_53230a_clients import Session

pytestmark = pytest.mark.timeout(30)

NO_ERROR = '0,"No error"'
SYNC = SyncLink(period_s=2.0, latency_s=3e-6)
TIE = TimeTie("fog-sync", sync_period_s=2.0, latency_s=3e-6)


@pytest.fixture
def stand():
    return turning_stand()


def errors(s: Session) -> list[str]:
    out = []
    while (e := s.query("SYST:ERR?")) != NO_ERROR:
        out.append(e)
    return out


# -- 6. FORMat REAL ------------------------------------------------------------------------

def test_pymeasure_format_real_gives_big_endian_definite_blocks(stand, twins: Twins) -> None:
    twin = twins.counter(stand, AXIS, model="pendulum-cnt-91")
    cnt = CNT91(twin.resource, visa_library="@py", timeout=10000)
    twins.close_later(cnt.adapter)
    visa = cnt.adapter.connection
    cnt.write("INP1:LEV 2.5")
    cnt.format = "REAL"
    assert cnt.format == "REAL" and cnt.check_errors() == []
    # one frequency: a definite-length block (`#18` + 8 bytes), big-endian
    visa.write(":MEAS:FREQ? (@1)")
    raw = visa.read_raw()
    assert raw[:3] == b"#18" and len(raw) == 3 + 8 + 1 and raw.endswith(b"\n")
    freq = float(np.frombuffer(raw[3:11], ">f8")[0])
    e = truth_edges(stand, twin.last_acquisition.t_start_s, np.inf)
    assert freq == pytest.approx(1.0 / (e[1] - e[0]), rel=1e-9)   # a 10 ms gate: a turn
    # an array, fetched as PyMeasure's read_buffer does, but binary
    cnt.configure_frequency_array_measurement(4, "A", back_to_back=True)
    cnt.gate_time = 0.5
    cnt.write(":INIT")
    while not cnt.complete:
        pass
    got = visa.query_binary_values(":FETC:ARR? 4", datatype="d", is_big_endian=True)
    e = truth_edges(stand, twin.last_acquisition.t_start_s, np.inf)[:5]
    np.testing.assert_allclose(got, 1.0 / np.diff(e), rtol=1e-9)
    # back to ASCII: PyMeasure's own buffer reading works as before
    cnt.buffer_frequency_time_series("A", 4, gate_time=0.5)
    assert cnt.format == "ASCII" and len(cnt.read_buffer(4)) == 4
    assert cnt.check_errors() == []


def test_form_packed_and_a_second_parameter_are_refused(stand, twins: Twins) -> None:
    twin = twins.counter(stand, AXIS, model="pendulum-cnt-91")
    s = twins.close_later(Session(twin))
    s.write("FORM PACK")
    assert errors(s) == ['-224,"Illegal parameter value"']    # not modelled
    s.write("FORM REAL,64")
    assert errors(s) == ['-108,"Parameter not allowed"']
    assert s.query("FORM?") == "ASC"


# -- 7. :MEASure:ARRay:TSTAmp?, :CONFigure:ARRay:TSTAmp, :MEASure:ARRay:STSTamp? -----------

def test_measure_array_tstamp_and_stst(stand, twins: Twins) -> None:
    twin = twins.counter(stand, AXIS, model="pendulum-cnt-91")
    s = twins.close_later(Session(twin))
    s.write("INP1:LEV 2.5")
    ts = np.array(s.query(":MEAS:ARR:TSTA? (4),(@1)").split(","), float)
    acq = twin.last_acquisition
    e = truth_edges(stand, acq.t_start_s, np.inf)[:4]
    assert ts.size == 4 and 0 < ts[0] <= PERIOD_S           # TS from the start event
    np.testing.assert_allclose(acq.t_start_s + ts, e, rtol=0, atol=50e-12)
    s.write("FORM:TINF ON")
    pairs = np.array(s.query("MEAS:ARR:TSTA? (3)").split(","), float)
    assert pairs.size == 6 and list(pairs[0::2]) == [1, 2, 3]
    s.write("FORM:TINF OFF")
    s.write(":CONF:ARR:TSTA (3),(@1)")
    s.write(":INIT")
    assert s.query("*OPC?") == "1"
    ts = np.array(s.query(":FETC:ARR? 3").split(","), float)
    e = truth_edges(stand, twin.last_acquisition.t_start_s, np.inf)[:3]
    np.testing.assert_allclose(twin.last_acquisition.t_start_s + ts, e, rtol=0, atol=50e-12)
    stst = np.array(s.query(":MEAS:ARR:STST? (2),(@1)").split(","), float)
    assert stst.size == 4 and list(stst[0::2]) == [1, 2]     # X,TS pairs (p. 8-72)
    assert errors(s) == []


# -- the timebase: [:SENSe]:ROSCillator:SOURce ---------------------------------------------

@pytest.mark.parametrize("wired", [True, False])
def test_reference_source_words(stand, twins: Twins, wired: bool) -> None:
    twin = twins.counter(stand, AXIS, model="pendulum-cnt-91",
                         truth=AxisTruth(counter_external_reference=wired))
    s = twins.close_later(Session(twin))
    s.write(":SENS:ROSC:SOUR INT")
    assert s.query("ROSC:SOUR?") == "INT"
    s.write("ROSC:SOUR AUTO")
    assert s.query(":SENSE:ROSCILLATOR:SOURCE?") == "AUTO"
    s.write("ROSC:SOUR EXTERNAL")
    if wired:
        assert errors(s) == [] and s.query("ROSC:SOUR?") == "EXT"
    else:   # nothing at the reference input: an error, the source as it was
        assert errors(s) == ['-241,"Hardware missing;no valid external reference signal"']
        assert s.query("ROSC:SOUR?") == "AUTO"


@pytest.mark.parametrize("wired", [True, False])
def test_driver_sets_and_checks_the_reference(stand, twins: Twins, wired: bool) -> None:
    twin = twins.counter(stand, AXIS, model="pendulum-cnt-91",
                         truth=AxisTruth(counter_external_reference=wired))
    with Counter.open(twin.resource, "pendulum-cnt-91", stand.clock) as counter:
        if wired:
            assert counter.verify_reference("external", 1e-9) == "EXT"
            assert counter.readback["counter.reference"] == "EXT"
            assert counter.verify_reference("internal", None) == "INT"
            with pytest.raises(CounterError, match="assumes an external reference"):
                counter.verify_reference(None, 1e-9)
        else:
            with pytest.raises(CounterCommandError, match=r"'ROSC:SOUR EXT'.*-241"):
                counter.verify_reference("external", 1e-9)
    assert PENDULUM_CNT91.has_reference_source and not PENDULUM_CNT91.has_reference_check


# -- the time tie: start arming on the FOG's sync pulse (ARM:SOUR EXT4) --------------------

def test_fog_sync_tie_arms_on_input_e_and_places_the_edges(stand, twins: Twins) -> None:
    twin = twins.counter(stand, AXIS, model="pendulum-cnt-91", sync=SYNC)
    with Counter.open(twin.resource, "pendulum-cnt-91", stand.clock, time_tie=TIE,
                      timeout_margin_s=1.0) as counter:
        counter.configure(channel=1, level_v=2.5)
        edges = counter.acquire_edges(5, PERIOD_S)
        acq = counter.last_acquisition
    assert "ARM:SOUR EXT4" in twin.received and "ARM:SOUR?" in twin.received
    assert counter.readback["counter.time_tie.source"] == "EXT4"
    t_pulse = twin.last_acquisition.t_start_s          # the pulse that started it
    assert acq.t_start_s == pytest.approx(round((t_pulse - 3e-6) / 2.0) * 2.0 + 3e-6,
                                          abs=1e-12)
    truth = truth_edges(stand, t_pulse, np.inf)[:5]
    np.testing.assert_array_less(np.abs(edges - truth), 0.5 * PENDULUM_CNT91.resolution_s
                                 + 1e-12)


def test_arming_on_a_or_b_is_a_clear_error(stand, twins: Twins) -> None:
    """Start arming on input A or B (PyMeasure's 'A'/'B': EXT1/EXT2) is not modelled:
    INIT is -221 rather than a measurement started at the wrong time."""
    twin = twins.counter(stand, AXIS, model="pendulum-cnt-91")
    s = twins.close_later(Session(twin))
    s.write("INP1:LEV 2.5;:CONF:ARR:STST (3),(@1);:ARM:SOUR EXT2")
    s.write("INIT")
    assert errors(s) == ['-221,"Settings conflict;start arming on input A or B is not '
                         'modelled by this twin"']
