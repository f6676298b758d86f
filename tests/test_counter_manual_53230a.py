"""The 53230A twin against its manual, where it once disagreed (issue 41).

Each test sends the Keysight 53220A/53230A Programmer's Reference's own sequence (or
SCPI-99's / IEEE 488.2's rule) over TCP and checks the manual's answer, numbers against
the stand's truth:
- TRIGger:SOURce BUS: INIT waits in wait-for-trigger until *TRG (IEEE 488.2 10.37);
  *TRG otherwise, or READ? with BUS, are -211 "Trigger ignored" / -214 "Trigger
  deadlock" (SCPI-99 vol. 2, 21.8.10);
- FORMat[:DATA] REAL: FETC? and READ? answer the indefinite-length block `#0<bytes>`
  then the terminator (FORMat:DATA page), R? a definite-length block (R? page);
- CONFigure:TINTerval [(@1),(@2)], CONFigure:TOTalize:TIMed [<gate>,][(@ch)],
  CONFigure:TSTamp [{<count>}][,(@ch)] with the reference's example `CONF:TST (5000)`;
- SAMPle:COUNt? / TRIGger:COUNt? {MIN|MAX|DEF}: 1, 1,000,000, 1;
- `SAMP:COUN 1,2`: -108 "Parameter not allowed" (SCPI-99 vol. 2, 21.8.9: more
  parameters than the header takes), not -102.
Before issue 41: BUS measured at INIT, *TRG was -113, FETC?/READ? REAL were definite
blocks, the three CONF words -113/-222, `SAMP:COUN? MAX` gave no reply and `TRIG:COUN?
MAX` answered +1, `SAMP:COUN 1,2` was -102.
"""

from __future__ import annotations

import struct
import time

import numpy as np
import pytest
import pyvisa

from sims.counter_twin import CounterTwin
from tests.conftest import Twins
from tests.counter_rig import AXIS, PERIOD_S, SPEED, truth_edges, turning_stand
from tests.test_transcript_53230a_clients import LEVEL, Session

pytestmark = pytest.mark.timeout(30)

NO_ERROR = '+0,"No error"'


@pytest.fixture
def rig(twins: Twins) -> tuple[object, CounterTwin, Session]:
    stand = turning_stand()
    twin = twins.counter(stand, AXIS, model="keysight-53230a")
    stand.clock.start()
    return stand, twin, twins.close_later(Session(twin))


def turns(n: float) -> None:
    """Let n turns of stand time pass (the virtual clock runs SPEED times real time)."""
    time.sleep(n * PERIOD_S / SPEED)


def errors(s: Session) -> list[str]:
    out = []
    while (e := s.query("SYST:ERR?")) != NO_ERROR:
        out.append(e)
    return out


# -- 1. TRIGger:SOURce BUS and *TRG --------------------------------------------------------

def test_bus_trigger_init_waits_for_trg_then_measures(rig) -> None:
    """TRIG:SOUR BUS; INIT: wait-for-trigger (nothing is measured, *ESR? shows no
    operation complete); *TRG starts it; the period is of the first turn after *TRG."""
    stand, twin, s = rig
    s.write("*RST;*CLS")
    s.write(LEVEL)
    s.write("CONF:PER (@1)")
    s.write("TRIG:SOUR BUS")
    assert s.query("TRIG:SOUR?") == "BUS"
    s.write("INIT;*OPC")
    turns(4)
    assert s.query("*ESR?") == "+0"             # still waiting for the bus trigger
    assert s.query("DATA:POIN?") == "+0"
    s.write("*TRG")
    assert errors(s) == []
    period = float(s.query("FETC?"))
    acq = twin.last_acquisition
    assert acq.triggers[0] - acq.t_arm_s > 3.0 * PERIOD_S    # not measured at INIT
    e = truth_edges(stand, acq.triggers[0], np.inf)
    assert period == pytest.approx(e[1] - e[0], abs=20e-12)
    assert s.query("*ESR?") == "+1"               # operation complete after the trigger


def test_bus_trigger_count_two_needs_two_triggers(rig) -> None:
    """TRIG:COUN 2, SAMP:COUN 1 with BUS: each *TRG takes one reading; a *TRG while
    nothing waits for one is -211 "Trigger ignored"."""
    stand, twin, s = rig
    s.write(LEVEL)
    s.write("CONF:PER (@1);:TRIG:SOUR BUS;COUN 2")
    s.write("INIT")
    turns(2)
    s.write("*TRG")
    turns(4)                                        # the first reading is done by now
    assert s.query("DATA:POIN?") == "+1"
    turns(3)
    s.write("*TRG")
    p = [float(v) for v in s.query("FETC?").split(",")]
    acq = twin.last_acquisition
    assert len(acq.triggers) == 2 and acq.triggers[1] - acq.triggers[0] > 6 * PERIOD_S
    for k in range(2):
        e = truth_edges(stand, acq.triggers[k], np.inf)
        assert p[k] == pytest.approx(e[1] - e[0], abs=20e-12)
    s.write("*TRG")                                 # measurement complete: ignored
    assert errors(s) == ['-211,"Trigger ignored"']


def test_bus_trigger_timestamps_count_from_the_trigger(rig) -> None:
    stand, twin, s = rig
    s.write(LEVEL)
    s.write("CONF:ARR:TST (3),(@1);:TRIG:SOUR BUS")
    s.write("INIT")
    turns(3)
    s.write("*TRG")
    values = [float(v) for v in s.query("FETC?").split(",")]
    t_trg = twin.last_acquisition.triggers[0]
    assert values[0] == 1 and t_trg - twin.last_acquisition.t_arm_s > 2 * PERIOD_S
    e = truth_edges(stand, t_trg, np.inf)[:3]
    np.testing.assert_allclose(t_trg + np.cumsum(values[1:]), e, rtol=0, atol=40e-12)


def test_trg_without_bus_and_read_with_bus_are_scpi_errors(rig) -> None:
    _, twin, s = rig
    s.write(LEVEL)
    s.write("*TRG")                               # TRIG:SOUR IMM (*RST): nothing waits
    assert errors(s) == ['-211,"Trigger ignored"']
    s.write("CONF:PER (@1);:TRIG:SOUR BUS")
    s.write("READ?;*OPC?")                        # READ? would wait for a *TRG: deadlock
    assert s.file.readline() == b"1\n"            # READ? answered nothing
    assert errors(s) == ['-214,"Trigger deadlock"']


# -- 2. FORMat:DATA REAL: FETC?/READ? indefinite, R? definite ------------------------------

def test_real_fetch_and_read_are_indefinite_blocks_r_is_definite(rig) -> None:
    stand, twin, s = rig
    s.write(LEVEL)
    s.write("FORM REAL,64")
    s.write("CONF:PER (@1);:SAMP:COUN 2")
    s.write("READ?")
    raw = s.file.read(2 + 16 + 1)
    assert raw[:2] == b"#0" and raw[-1:] == b"\n"   # `#0`, 2 doubles, the terminator
    e = truth_edges(stand, twin.last_acquisition.t_start_s, np.inf)
    np.testing.assert_allclose(struct.unpack(">2d", raw[2:18]), e[1:4:2] - e[0:4:2],
                               atol=40e-12)
    s.write("INIT")
    s.write("FETC?")
    assert len(s.read_indefinite(16)) == 16
    s.write("INIT;*WAI")
    s.write("R?")
    block = s.read_block()                          # `#216` + 16 bytes: definite
    e = truth_edges(stand, twin.last_acquisition.t_start_s, np.inf)
    np.testing.assert_allclose(struct.unpack(">2d", block), e[1:4:2] - e[0:4:2],
                               atol=40e-12)
    assert errors(s) == []


def test_pyvisa_reads_the_indefinite_block_by_its_count(rig) -> None:
    """pyvisa's query_binary_values (an independent client): `#0` blocks are read by the
    number of points the caller expects (data_points), big-endian (FORM:BORD NORM)."""
    stand, twin, s = rig
    s.close()
    inst = pyvisa.ResourceManager("@py").open_resource(
        twin.resource, read_termination="\n", write_termination="\n", timeout=10000)
    try:
        inst.write(LEVEL)
        inst.write("FORM REAL;:CONF:ARR:TST (3),(@1)")
        values = inst.query_binary_values("READ?", datatype="d", is_big_endian=True,
                                          data_points=4)
        t0 = twin.last_acquisition.t_start_s
        assert values[0] == 1.0
        e = truth_edges(stand, t0, np.inf)[:3]
        np.testing.assert_allclose(t0 + np.cumsum(values[1:]), e, rtol=0, atol=40e-12)
        assert inst.query("SYST:ERR?") == NO_ERROR
    finally:
        inst.close()


def test_the_bench_driver_asks_for_ascii_and_reads_it(rig) -> None:
    """drivers/counter.py sends FORM ASCii before every INIT: a twin left in REAL by a
    script still answers the driver in ASCII."""
    from drivers.counter import Counter
    stand, twin, s = rig
    s.write("FORM REAL")
    s.close()
    with Counter.open(twin.resource, "keysight-53230a", stand.clock) as counter:
        counter.configure(level_v=2.5)
        assert counter.acquire_periods(2, PERIOD_S).size == 2
    assert "FORM ASCii" in twin.received and twin.data_format == "ASC"


# -- 3. CONF:TINT, CONF:TOT:TIM, CONF:TST (5000) -------------------------------------------

def test_configure_time_interval_is_accepted_and_measuring_it_is_minus_221(rig) -> None:
    _, twin, s = rig
    s.write("CONF:TINT (@1),(@2)")
    assert s.query("CONF?") == '"TINT (@1),(@2)"'
    s.write("CONF:TINT")
    assert s.query("CONF?") == '"TINT (@1),(@2)"'     # the reference's default
    s.write("CONF:TINT (@2),(@1)")
    assert s.query("CONF?") == '"TINT (@2),(@1)"'
    assert errors(s) == []
    s.write("INIT")                                    # not modelled: a clear error
    s.write("READ?;*OPC?")
    assert s.file.readline() == b"1\n"
    errs = errors(s)
    assert len(errs) == 2 and all(e.startswith('-221,"Settings conflict;time interval')
                                  for e in errs)


def test_configure_totalize_timed_counts_the_marks_in_the_gate(rig) -> None:
    stand, twin, s = rig
    s.write(LEVEL)
    s.write("CONF:TOT:TIM 3.5,(@1)")
    assert s.query("CONF?") == '"TOT:TIM +3.50000000000000E+000,(@1)"'
    count = float(s.query("READ?"))
    t0 = twin.last_acquisition.t_start_s
    assert count == truth_edges(stand, t0, t0 + 3.5).size and count in (3, 4)
    s.write("CONF:TOT:TIM")
    assert s.query("CONF?") == '"TOT:TIM +1.00000000000000E-001,(@1)"'
    s.write("CONF:TOT:TIM (@2)")
    assert s.query("CONF?").endswith(',(@2)"')
    assert errors(s) == []


def test_the_references_conf_tst_example(rig) -> None:
    """`CONF:TST (5000)`: 5000 time stamps of channel 1; `CONF:TST 4,(@2)` too."""
    stand, twin, s = rig
    s.write("CONF:TST (5000)")
    assert errors(s) == []
    assert s.query("CONF?") == '"TST (@1)"' and s.query("SAMP:COUN?") == "+5000"
    s.write("CONF:TST 4,(@2)")
    assert s.query("CONF?") == '"TST (@2)"' and s.query("SAMP:COUN?") == "+4"
    s.write(LEVEL)
    s.write("CONF:TST (3)")
    values = s.query("READ?").split(",")
    t0 = twin.last_acquisition.t_start_s
    assert values[0] == "+1" and len(values) == 4
    np.testing.assert_allclose(t0 + np.cumsum([float(v) for v in values[1:]]),
                               truth_edges(stand, t0, np.inf)[:3], rtol=0, atol=40e-12)
    assert errors(s) == []


# -- 4. SAMP:COUN? / TRIG:COUN? MIN, MAX, DEF ----------------------------------------------

def test_count_queries_answer_their_limits(rig) -> None:
    _, twin, s = rig
    s.write("SAMP:COUN 7;:TRIG:COUN 3")
    for word, now in (("SAMP:COUN", "+7"), ("TRIG:COUN", "+3")):
        assert s.query(f"{word}? MAX") == "+1000000"
        assert s.query(f"{word}? MIN") == "+1"
        assert s.query(f"{word}? DEF") == "+1"
        assert s.query(f"{word}?") == now               # the setting is left alone
    s.write("SAMP:COUN MAX;:TRIG:COUN MAX")
    assert s.query("SAMP:COUN?;:TRIG:COUN?") == "+1000000;+1000000"
    assert s.query("TRIG:DEL? MAX") == "+3.60000000000000E+003"
    assert errors(s) == []


# -- 5. too many parameters: -108 ----------------------------------------------------------

def test_too_many_parameters_is_minus_108(rig) -> None:
    _, twin, s = rig
    for line in ("SAMP:COUN 1,2", "TRIG:COUN 1,2", "INP1:LEV 2.5,3", "SAMP:COUN? MAX,MIN"):
        s.write(line)
        assert errors(s) == ['-108,"Parameter not allowed"'], line
    assert twin.sample_count == 1 and twin.trigger_count == 1
