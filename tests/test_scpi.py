"""The SCPI bases: commands as data (drivers/scpi.py) and the TCP server (sims/scpi_server.py).

Expected values are SCPI's rules written out by hand (short forms, optional nodes,
suffixes, error codes and ESR bits of IEEE 488.2 / SCPI-99), not the code's output.
"""

from __future__ import annotations

import socket
import threading
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.scpi import (
    ABORT,
    Command,
    Control,
    ErrorEntry,
    InstrumentCommandError,
    InstrumentReplyError,
    Measurement,
    ParameterError,
    ScpiInstrument,
    Setting,
    format_value,
    in_range,
    one_of,
    parse_numbers,
)
from sims.scpi_server import ScpiServer

pytestmark = pytest.mark.timeout(20)

LEVEL = Command("INPut{channel}:LEVel[1][:ABSolute]", "{level_v}")
RATE = Command("[SENSe:]TSTamp:RATE", "{rate_hz}")
CONF_TST = Command("CONFigure:ARRay:TSTamp", "({count}),(@{channel})")


# -- commands as data ------------------------------------------------------------------------

def test_text_is_the_short_form_without_optional_nodes():
    assert LEVEL.text(channel=2, level_v=1.5) == "INP2:LEV 1.5"
    assert RATE.text(rate_hz=1e4) == "TST:RATE 10000"
    assert CONF_TST.text(count=6, channel=1) == "CONF:ARR:TST (6),(@1)"
    assert LEVEL.query_text(channel=1) == "INP1:LEV?"
    assert Command("*IDN?").text() == "*IDN?"
    with pytest.raises(KeyError, match="needs channel"):
        LEVEL.text(level_v=1.0)


@pytest.mark.parametrize("header,suffix", [
    ("INP2:LEV", "2"), (":input2:level1:absolute", "2"), ("INPUT:LEV:ABS", ""),
    ("Inp1:Level1", "1"),
])
def test_match_accepts_short_long_optional_and_any_case(header, suffix):
    assert LEVEL.match(header) == {"channel": suffix}


@pytest.mark.parametrize("header", ["INP2:LEVE", "INPU:LEV", "INP2:LEV:ABSO:X", "LEV", "INP2:LEV?"])
def test_match_refuses_what_scpi_does_not_allow(header):
    assert LEVEL.match(header) is None


def test_query_forms():
    assert LEVEL.match("INP1:LEV?", query=True) == {"channel": "1"}
    idn = Command("*IDN?")
    assert idn.match("*idn?") == {} and idn.match("*IDN") is None
    assert RATE.match("sense:tstamp:rate") == {} and RATE.match("TST:RATE") == {}


_NODES = ["CONFigure", "ARRay", "TSTamp"]


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.booleans(), st.booleans()), min_size=3, max_size=3),
       st.booleans())
def test_any_mix_of_short_long_and_case_matches(forms, colon):
    parts = []
    for node, (long, upper) in zip(_NODES, forms, strict=True):
        word = node if long else "".join(c for c in node if c.isupper())
        parts.append(word.upper() if upper else word.lower())
    assert CONF_TST.match((":" if colon else "") + ":".join(parts)) == {}


def test_parse_params_and_their_error_codes():
    assert CONF_TST.parse_params("( 5 ), (@1)") == {"count": "5", "channel": "1"}
    # SCPI-99 vol. 2, 21.8.9: more parameters than the header takes is -108
    for text, code in [("", -109), ("5,1", -102), ("(5),(@1),3", -108),
                       ("(5),(@1,2)x", -102)]:
        with pytest.raises(ParameterError) as e:
            CONF_TST.parse_params(text)
        assert e.value.code == code
    with pytest.raises(ParameterError) as e:
        ABORT.parse_params("NOW")
    assert e.value.code == -108
    with pytest.raises(ParameterError) as e:
        RATE.parse_params("1E4,2")
    assert e.value.code == -108


def test_values_replies_and_error_entries():
    assert [format_value(v) for v in (True, False, 7, 2.5, 1e6, 2e-11, "MIN")] == \
        ["ON", "OFF", "7", "2.5", "1000000", "2E-11", "MIN"]
    np.testing.assert_array_equal(parse_numbers("+1,+1.29E-006, -2.5E+003\n"),
                                  [1.0, 1.29e-6, -2500.0])
    with pytest.raises(ValueError, match="empty field"):
        parse_numbers("1,,2")
    assert ErrorEntry.parse('-113,"Undefined header"') == ErrorEntry(-113, "Undefined header")
    assert ErrorEntry.parse('+0,"No error"').code == 0
    with pytest.raises(ValueError):  # a late data reply is not an error entry
        ErrorEntry.parse("+1,+1.0E+000")


# -- a small instrument on the server base, and a driver with properties as data ---------

GAIN = Command("SOURce{channel}:GAIN", "{value}", doc="gain of a channel")
VALUE = Command("MEASure:VALue?", doc="a reading that waits for `release`")


class Box(ScpiServer):
    def __init__(self) -> None:
        super().__init__(idn="Test,Box,1,0")
        self.gain = {1: 1.0, 2: 1.0}
        self.release = threading.Event()
        self.route(GAIN, on_set=self._set_gain,
                   on_query=lambda a: f"{self.gain[int(a['channel'] or 1)]:+.6E}")
        self.route(VALUE, on_query=self._value, data=True)
        self.route(ABORT, on_set=lambda a: None)

    def _set_gain(self, a):
        self.gain[int(a["channel"] or 1)] = float(a["value"])

    def _value(self, a):
        self.wait(self.release.is_set)
        return "+4.2E+00"


class BoxDriver(ScpiInstrument):
    words = {"gain": GAIN}
    gain = Control("gain", cast=float, validator=in_range(0, 10))
    gain_only = Setting(GAIN, validator=one_of(0.5, 1, 2))
    value = Measurement(VALUE, cast=float)
    channel = 1

    def template_values(self):
        return {"channel": self.channel}


@pytest.fixture
def box():
    with Box() as server:
        yield server


def test_properties_declared_as_data(box):
    log = []
    with BoxDriver(box.resource, raw=lambda d, b: log.append((d, b))) as drv:
        drv.channel = 2
        drv.gain = 3.5
        assert box.gain == {1: 1.0, 2: 3.5} and drv.gain == 3.5
        drv.channel = 1
        drv.gain_only = 2
        assert box.gain[1] == 2.0
        with pytest.raises(ValueError, match=r"gain = 11.*within \[0, 10\]"):
            drv.gain = 11
        box.release.set()
        assert drv.value == 4.2
    assert ("tx", b"SOUR2:GAIN 3.5\n") in log and ("rx", b"+3.500000E+00\n") in log
    assert ("tx", b"SYST:ERR?\n") in log                       # checked writes
    assert BoxDriver.gain_only.__doc__ == "gain of a channel"   # from the Command


def test_error_queue_codes_order_overflow_and_esr(box):
    with BoxDriver(box.resource) as drv:
        drv.write("SOUR1:GAIN", check=False)          # -109 missing parameter
        drv.write("*CLS 1", check=False)              # -108 parameter not allowed
        drv.write("SOUR1:GAIM 2", check=False)        # -113 undefined header
        assert [e.code for e in drv.drain_errors()] == [-109, -108, -113]
        assert int(drv.query("*ESR?")) == 0x20        # command error bit, then cleared
        assert int(drv.query("*ESR?")) == 0
        for _ in range(25):
            drv.write("NOPE", check=False)
        errors = drv.drain_errors()
        assert len(errors) == 20 and errors[-1] == ErrorEntry(-350, "Queue overflow")
        drv.write("NOPE", check=False)
        drv.write("*CLS")
        assert drv.drain_errors() == []
        with pytest.raises(InstrumentCommandError, match=r"'NOPE'.*-113"):
            drv.write("NOPE")


def test_an_error_already_queued_is_not_blamed_on_the_next_command(box):
    """An unchecked command leaves -113 in the queue; the next checked (valid) command is
    reported as clean, and the old error as queued before it (issue 13's 'ABOR')."""
    with BoxDriver(box.resource) as drv:
        drv.write("NOPE", check=False)
        with pytest.raises(InstrumentCommandError) as info:
            drv.write("SOUR1:GAIN 2")
        text = str(info.value)
        assert "after 'SOUR1:GAIN 2'" not in text, text
        assert "before 'SOUR1:GAIN 2' its error queue already held -113" in text, text
        assert "from 'NOPE'" in text
        drv.write("SOUR1:GAIN 3")                     # the queue is clean again
        assert drv.query("SOUR1:GAIN?") == "+3.000000E+00"


def test_several_units_in_one_message_answer_on_one_line(box):
    with BoxDriver(box.resource) as drv:
        assert drv.query("*IDN?;SOUR1:GAIN 5;:SOUR1:GAIN?") == "Test,Box,1,0;+5.000000E+00"


def _line(sock: socket.socket) -> bytes:
    data = b""
    while not data.endswith(b"\n"):
        chunk = sock.recv(1024)
        if not chunk:
            break
        data += chunk
    return data


def test_clients_are_served_one_after_another(box):
    a = socket.create_connection((box.host, box.port), timeout=2)
    b = socket.create_connection((box.host, box.port), timeout=0.3)
    a.sendall(b"*IDN?\n")
    assert _line(a) == b"Test,Box,1,0\n"
    b.sendall(b"*IDN?\n")
    with pytest.raises(TimeoutError):              # queued behind a
        b.recv(1024)
    a.close()
    b.settimeout(2)
    assert _line(b) == b"Test,Box,1,0\n"
    b.close()
    assert box.sessions >= 1


def test_abort_ends_a_waiting_query_without_reply(box):
    with socket.create_connection((box.host, box.port), timeout=2) as s:
        s.sendall(b"MEAS:VAL?\n")
        time.sleep(0.1)
        s.sendall(b"ABOR\n*OPC?\n")
        assert _line(s) == b"1\n"                  # no reply to MEAS:VAL?, then *OPC?


def test_faults_hit_data_queries_only(box):
    box.release.set()
    with BoxDriver(box.resource, command_timeout_s=0.3) as drv:
        box.inject("garbage")
        assert drv.query("*IDN?") == "Test,Box,1,0"     # not a data query
        with pytest.raises(InstrumentReplyError, match="not ASCII"):
            _ = drv.value
        assert drv.value == 4.2                         # once only
        box.inject("drop")
        with pytest.raises(Exception, match="no reply"):
            _ = drv.value
        assert "reopened" in drv.recover()
        assert drv.value == 4.2 and box.sessions == 2


def test_stop_returns_promptly_with_a_client_waiting():
    box = Box()
    box.start()
    s = socket.create_connection((box.host, box.port), timeout=2)
    s.sendall(b"MEAS:VAL?\n")
    time.sleep(0.05)
    t0 = time.monotonic()
    box.stop()
    assert time.monotonic() - t0 < 1.0
    assert s.recv(1024) == b""                           # the session was closed
    s.close()
