"""PyMeasure's own CNT-91 driver (pymeasure.instruments.pendulum.cnt91.CNT91), an
independent client, against the CNT-91 twin over pyvisa-py's TCPIP SOCKET (issue 24).

Every documented method and property of the driver is used as its docstrings say; the
values are checked against the stand's truth (a frequency reading of the zero mark is
turns / time between the edges that closed its gate, CNT-90 series Programmer's
Handbook :ACQuisition:APERture, :CONFigure:ARRay:FREQuency[:BTB], :FETCh:ARRay?).
Before issue 24, FORM:SMAX?, INIT:CONT, ACQ:APER, ARM:SOUR, CAL:INT:AUTO?,
CONF:ARR:FREQ:BTB, *STB?, *OPT? were -113, so buffer_frequency_time_series() and
read_buffer() failed.
"""

from __future__ import annotations

import numpy as np
import pytest
from pymeasure.instruments.pendulum.cnt91 import CNT91

from sims.counter_twin import CounterTwin
from tests.conftest import Twins
from tests.counter_rig import AXIS, truth_edges, turning_stand

pytestmark = pytest.mark.timeout(30)


@pytest.fixture
def rig(twins: Twins) -> tuple[object, CounterTwin, CNT91]:
    stand = turning_stand()
    twin = twins.counter(stand, AXIS, model="pendulum-cnt-91")
    cnt = CNT91(twin.resource, visa_library="@py", timeout=10000)
    twins.close_later(cnt.adapter)
    return stand, twin, cnt


def test_identity_reset_status_options_and_settings(rig) -> None:
    _, twin, cnt = rig
    assert "CNT-91" in cnt.id
    cnt.reset()
    cnt.clear()
    assert cnt.status == "0" and cnt.options == "0"
    assert cnt.batch_size == 10000                       # FORM:SMAX? (p. 8-39)
    cnt.format = "ASCII"
    assert cnt.format == "ASCII"
    cnt.continuous = False
    assert cnt.continuous is False
    cnt.gate_time = 0.25
    assert cnt.gate_time == pytest.approx(0.25)
    cnt.external_start_arming_source = "B"
    assert cnt.external_start_arming_source == "B"
    cnt.external_start_arming_source = "IMM"
    cnt.external_arming_start_slope = "NEG"
    assert cnt.external_arming_start_slope == "NEG"
    cnt.interpolator_autocalibrated = False
    assert cnt.interpolator_autocalibrated is False
    assert cnt.check_errors() == []


@pytest.mark.parametrize("back_to_back", [True, False])
def test_buffer_frequency_time_series_and_read_buffer(rig, back_to_back: bool) -> None:
    stand, twin, cnt = rig
    cnt.write("INP1:LEV 2.5")          # the zero-mark pulse's level (no auto-level on it)
    cnt.buffer_frequency_time_series("A", 5, gate_time=1.5, back_to_back=back_to_back)
    freq = np.asarray(cnt.read_buffer(5))
    acq = twin.last_acquisition
    e = truth_edges(stand, acq.t_start_s, np.inf)
    # gate 1.5 s on 1 s turns: each reading spans two turns; back to back they share
    # their end edge with the next reading's start, otherwise the next edge starts it
    step = 2 if back_to_back else 3
    starts = np.arange(5) * step
    truth = 2.0 / (e[starts + 2] - e[starts])
    np.testing.assert_allclose(freq, truth, rtol=1e-9)
    assert cnt.check_errors() == []


def test_configure_array_then_fetch_in_batches(rig) -> None:
    stand, twin, cnt = rig
    cnt.write("INP1:LEV 2.5")
    cnt.configure_frequency_array_measurement(6, "A")
    cnt.gate_time = 0.5
    cnt.write(":INIT")
    first = cnt.read_buffer(4)
    rest = cnt.values(":FETC:ARR? 2")
    freq = np.concatenate([first, rest])
    e = truth_edges(stand, twin.last_acquisition.t_start_s, np.inf)[:7]
    np.testing.assert_allclose(freq, 1.0 / np.diff(e), rtol=1e-9)
