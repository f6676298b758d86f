"""The 53230A twin as public client programs script a 53230A, over TCP (issue 24).

Each test replays what one program sends, read from its repository (file named at the
test), over a plain socket or pyvisa-py's TCPIP SOCKET, and checks the replies against
the stand's truth and the Keysight 53220A/53230A Programmer's Reference (replies with
15 significant digits and 3 exponent digits as in its SENSe:TSTamp:RATE example
`+1.29383828200000E-006`; FORMat REAL,64 as an IEEE 488.2 definite-length block;
SCPI-99 vol. 1 6.2.4 header compounding after `;`; an unknown header is -113 with no
reply). Before issue 24 every one of these 17 words was -113 and the client waited for
its timeout.
"""

from __future__ import annotations

import re
import socket
import struct

import numpy as np
import pytest
import pyvisa

from sims.counter_twin import CounterTwin
from tests.conftest import Twins
from tests.counter_rig import AXIS, truth_edges, turning_stand

pytestmark = pytest.mark.timeout(30)

NR3_15 = re.compile(r"^[+-]\d\.\d{14}E[+-]\d{3}$")


class Session:
    """A raw SCPI socket as the C# and Python clients open it (port 5025, `\\n`)."""

    def __init__(self, twin: CounterTwin) -> None:
        port = int(twin.resource.split("::")[2])
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=10)
        self.file = self.sock.makefile("rb")

    def write(self, text: str) -> None:
        self.sock.sendall(text.encode("ascii") + b"\n")

    def query(self, text: str) -> str:
        self.write(text)
        return self.file.readline().decode("ascii").rstrip("\n")

    def read_block(self) -> bytes:
        head = self.file.read(2)
        assert head[:1] == b"#"
        digits = int(head[1:2])
        length = int(self.file.read(digits)) if digits else 0
        data = self.file.read(length)
        assert self.file.read(1) == b"\n"
        return data

    def read_indefinite(self, n_bytes: int) -> bytes:
        """An IEEE 488.2 indefinite-length block, `#0<bytes>` then the terminator (FETC?,
        READ? in FORM REAL): the reader knows how many bytes its readings make."""
        assert self.file.read(2) == b"#0"
        data = self.file.read(n_bytes)
        assert self.file.read(1) == b"\n"
        return data

    def close(self) -> None:
        self.file.close()
        self.sock.close()


@pytest.fixture
def rig(twins: Twins) -> tuple[object, CounterTwin, Session]:
    stand = turning_stand()
    twin = twins.counter(stand, AXIS, model="keysight-53230a")
    return stand, twin, twins.close_later(Session(twin))


def no_error(s: Session) -> None:
    assert s.query("SYST:ERR?") == '+0,"No error"'


LEVEL = "INP1:LEV:AUTO OFF;:INP1:LEV 2.5"   # the bench's zero-mark pulse (not in the clients)


def test_joewhalen_keysight_test_py_streams_frequencies_with_r_query(rig) -> None:
    """joewhalen/keysight_53230A keysight_test.py: *RST; SENS:FREQ:GATE:TIME; SENS:FREQ:MODE
    REC; TRIG:SOUR IMM; COUN MAX; INIT; then R? in a loop (counter.py strips up to '+')."""
    stand, twin, s = rig
    s.write("*RST")
    s.write("SENS:FREQ:GATE:TIME 0.1;")
    s.write("SENS:FREQ:MODE REC;")
    s.write("TRIG:SOUR IMM; COUN MAX")          # header compounding: TRIG:COUN MAX
    s.write(LEVEL)
    no_error(s)
    assert s.query("TRIG:COUN?") == "+1000000"
    s.write("INIT")
    got: list[float] = []
    while len(got) < 3:
        s.write("R?")
        block = s.read_block().decode("ascii")
        if block:                                    # `#10` while nothing is in memory
            got += [float(v) for v in block.split(",")]
    assert all(NR3_15.match(v) for v in block.split(","))
    edges = truth_edges(stand, twin.last_acquisition.t_start_s, np.inf)
    true_freq = 1.0 / (edges[1:6:2] - edges[0:6:2])  # every other turn: readings have dead time
    np.testing.assert_allclose(got[:3], true_freq, rtol=1e-9)
    no_error(s)


def test_joewhalen_counter_py_one_line_path_is_minus_113_as_scpi_says(rig) -> None:
    """joewhalen/keysight_53230A counter.py sends `SENS:FREQ:GATE:TIME x; SENS:FREQ:MODE REC;`
    in one message: after `;` the path is SENS:FREQ:GATE, so the second header is
    SENS:FREQ:GATE:SENS:FREQ:MODE, which the instrument refuses (-113), no reply."""
    _, twin, s = rig
    s.write("SENS:FREQ:GATE:TIME 0.1; SENS:FREQ:MODE REC;")
    assert s.query("SYST:ERR?") == '-113,"Undefined header"'
    assert twin.frequency_mode == "AUTO"


def test_opronningen_r_cs_removes_readings_with_wait(rig) -> None:
    """opronningen/53230A-Toolkit R/R.cs: `ABORT;*WAI;INIT:IMM`, then `:DATA:REMOVE? n,WAIT`
    in a loop; Ag53230A.cs ReadErrors sends `;SYST:ERR?` until `+0,`."""
    stand, twin, s = rig
    s.write(LEVEL)
    s.write("CONF:ARR:TST (4),(@1)")
    s.write("ABORT;*WAI;INIT:IMM")
    first = s.query(":DATA:REMOVE? 2,WAIT").split(",")
    t0 = twin.last_acquisition.t_start_s
    assert first[0] == "+1"                       # the prescaler is the first reading
    rest = s.query(":DATA:REMOVE? 3,WAIT").split(",")
    intervals = np.array([float(v) for v in first[1:] + rest])
    edges = truth_edges(stand, t0, np.inf)[:4]
    np.testing.assert_allclose(np.cumsum(intervals), edges - t0, atol=40e-12)
    assert s.query("DATA:POIN?") == "+0"
    assert s.query(";SYST:ERR?").startswith("+0,")


def test_opronningen_learn_and_real64_readings(rig) -> None:
    """Ag53230A.cs: `Abort;*WAI;*LRN?` split at `;` into `KEY VALUE` settings (FORM
    `ASC,15` or `REAL,64`, FORM:BORD NORM/SWAP, :TRIG:COUN, :TRIG:DEL, :TRIG:SLOP,
    :SAMP:COUN); 8-byte doubles (SWAP: little-endian). READ? answers them in the
    indefinite-length block `#0...` the Programmer's Reference's FORMat:DATA page shows
    (issue 41; the definite `#<n><len>` block ReadReals parses is R?'s)."""
    stand, twin, s = rig
    s.write(LEVEL)
    s.write(":TRIG:SLOP POS;:TRIG:DEL 0.25;:SAMP:COUN 2")
    learned = dict(item.split(" ", 1) for item in
                   s.query("Abort;*WAI;*LRN?").split(";")[1:])
    assert learned["FORM"] == "ASC,15" and learned["FORM:BORD"] == "NORM"
    assert learned[":TRIG:SLOP"] == "POS" and learned[":SAMP:COUN"] == "+2"
    assert float(learned[":TRIG:DEL"]) == 0.25 and NR3_15.match(learned[":TRIG:DEL"])
    s.write("FORM REAL,64")
    s.write("FORM:BORD SWAP")
    s.write(":CONF:PER DEF,DEF,(@1)")
    s.write(":SAMP:COUN 2")
    no_error(s)
    s.write("READ?")
    data = s.read_indefinite(16)
    t0 = twin.last_acquisition.t_start_s
    periods = struct.unpack("<2d", data)
    edges = truth_edges(stand, t0, np.inf)
    np.testing.assert_allclose(periods, edges[1:4:2] - edges[0:4:2], atol=40e-12)
    assert s.query("FORM?") == "REAL,64"
    s.write("FORM ASC,15")
    assert s.query("FORM?") == "ASC,15"


def test_francescobenfenati_socket_read_query_parses_as_a_float(rig) -> None:
    """francescobenfenati/Agilent-53230A-remote-control socket_agilent.py:
    `READ?` on a raw socket, `float(s.recv(1024).decode())`."""
    stand, twin, s = rig
    s.write(LEVEL)
    s.write("CONF:PER (@1)")
    reply = s.query("READ?")
    assert NR3_15.match(reply)
    t0 = twin.last_acquisition.t_start_s
    edges = truth_edges(stand, t0, np.inf)
    assert float(reply) == pytest.approx(edges[1] - edges[0], abs=20e-12)


def test_measure_and_status_words_through_pyvisa(rig) -> None:
    """The rest of the 17: MEAS:ARR:TST? (the page the driver cites, p. 240), MEAS:PER?,
    MEAS:FREQ?, CONF:TST, CONF?, *STB?, SYST:VERS?, TRIG:COUN, FORM:BORD?, SENS:FREQ:MODE?."""
    stand, twin, s = rig
    s.close()
    rm = pyvisa.ResourceManager("@py")
    inst = rm.open_resource(twin.resource, read_termination="\n", write_termination="\n",
                            timeout=10000)
    try:
        inst.write(LEVEL)
        tst = inst.query("MEAS:ARR:TST? (3),(@1)").split(",")
        assert tst[0] == "+1" and len(tst) == 4 and all(NR3_15.match(v) for v in tst[1:])
        per = float(inst.query("MEAS:PER? DEF,DEF,(@1)"))
        freq = float(inst.query("MEAS:FREQ? (@1)"))
        assert per == pytest.approx(1.0, rel=1e-3) and freq == pytest.approx(1.0, rel=1e-3)
        assert inst.query("CONF?") == '"FREQ (@1)"'
        inst.write("CONF:TST (@1)")
        assert inst.query("CONF?") == '"TST (@1)"'
        assert inst.query("*STB?") == "+0"
        inst.write("BOGUS:WORD 1")                     # unknown: -113, no reply, STB bit 2
        assert inst.query("*STB?") == "+4"
        assert inst.query("SYST:ERR?") == '-113,"Undefined header"'
        assert inst.query("SYST:VERS?") == "1994.0"
        assert inst.query("FORM:BORD?") == "NORM"
        assert inst.query("SENS:FREQ:MODE?") == "AUTO"
        inst.write("TRIG:COUN 0")
        assert inst.query("SYST:ERR?") == '-222,"Data out of range"'
    finally:
        inst.close()


def test_white_rabbit_ks53230_period_freq_and_trigger_settings(rig) -> None:
    """TimingKeepers/measuring_instr driver/ks53230.py (the White Rabbit calibration
    tool's KS53230 class): configureTrigger sends `TRIGGer:COUNt n`, `TRIGGer:DELay
    0.000000`, `TRIGGer:SOURce imm`, `TRIGGer:SLOPe pos`; period() and freq() send
    `CONF:PER DEF,DEF,(@1)` / `CONF:FREQ DEF,DEF,(@1)`, trigLevel `INPUT1:LEVEL:AUTO OFF`,
    `INPUT1:LEVEL 2.500`, then `INPUT1:COUPLING DC`, `INIT`, `READ?`."""
    stand, twin, s = rig
    for line in ("TRIGGer:COUNt 1", "TRIGGer:DELay 0.000000", "TRIGGer:SOURce imm",
                 "TRIGGer:SLOPe pos"):
        s.write(line)
    no_error(s)
    assert (twin.trigger_source, twin.trigger_slope, twin.trigger_count) == ("IMM", "POS", 1)
    for conf, invert in (("CONF:PER DEF,DEF,(@1)", False), ("CONF:FREQ DEF,DEF,(@1)", True)):
        s.write(conf)
        s.write("INPUT1:LEVEL:AUTO OFF")
        s.write("INPUT1:LEVEL 2.500")
        s.write("INPUT1:COUPLING DC")
        s.write("INIT")
        reply = s.query("READ?")
        t0 = twin.last_acquisition.t_start_s
        e = truth_edges(stand, t0, np.inf)
        period = e[1] - e[0]
        assert float(reply) == pytest.approx(1.0 / period if invert else period, rel=1e-10)
    no_error(s)
