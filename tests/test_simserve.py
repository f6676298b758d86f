"""`bench sim STAND.yaml` (CONTRACT §1) as a user meets it: started in one process, its
twins driven from another with the clients a user's own script would use (pyvisa on the
printed resource, canopen's BaseNode402 on the printed udp_multicast bus, pyserial on the
printed pty). Nothing here is a mock: three processes' worth of real channels."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import canopen
import pytest
import pyvisa
import serial
from canopen.profiles.p402 import BaseNode402

from drivers.cia402 import DEFAULT_EDS_PATH

ROOT = Path(__file__).resolve().parents[1]
STAND = ROOT / "configs" / "stands" / "sim-two-axis.yaml"

pytestmark = pytest.mark.timeout(90)


def _addresses(proc: subprocess.Popen[str], n: int, timeout_s: float) -> dict[tuple[str, str],
                                                                             list[str]]:
    out: dict[tuple[str, str], list[str]] = {}
    deadline = time.monotonic() + timeout_s
    assert proc.stdout is not None
    while len(out) < n and time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        axis, kind, *address = line.split()
        out[(axis, kind)] = address
    return out


def test_bench_sim_twins_driven_from_another_process() -> None:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "bench", "sim", str(STAND)], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env)
    try:
        found = _addresses(proc, 6, 60.0)
        assert set(found) == {(a, k) for a in ("outer", "inner")
                              for k in ("counter", "fog", "drive")}, found
        # the counter: pyvisa (pyvisa-py) on the printed resource
        rm = pyvisa.ResourceManager("@py")
        inst = rm.open_resource(found[("outer", "counter")][0], read_termination="\n",
                                write_termination="\n", timeout=5000)
        try:
            assert "53230A" in inst.query("*IDN?")
            assert inst.query("SYST:ERR?").startswith("+0")
        finally:
            inst.close()
        # the FOG: frames on the printed pty (KVH format A: header 0xFE81FF55)
        with serial.Serial(found[("outer", "fog")][0], 921600, timeout=2.0) as fog:
            assert b"\xfe\x81\xff\x55" in fog.read(400)
        # the drive: canopen's BaseNode402 on the printed bus
        fields = dict(f.split("=", 1) for f in found[("outer", "drive")])
        assert fields["interface"] == "udp_multicast"
        network = canopen.Network()
        network.connect(interface="udp_multicast", channel=fields["channel"],
                        port=int(fields["port"]))
        try:
            node = BaseNode402(int(fields["node"]), str(DEFAULT_EDS_PATH))
            network.add_node(node)
            node.sdo.RESPONSE_TIMEOUT = 2.0
            # TPDOs only: on udp_multicast a process hears its own frames, and canopen
            # then takes its own RPDOs for periodic ones and stops sending them; the
            # controlword goes by SDO (BaseNode402's fallback)
            node.tpdo.read()
            node.setup_402_state_machine(read_pdos=False)
            node.nmt.state = "OPERATIONAL"
            time.sleep(0.2)
            node.op_mode = "PROFILED VELOCITY"
            node.sdo[0x60FF].raw = 0
            node.state = "OPERATION ENABLED"
            rate_dps = 10.0
            node.sdo[0x60FF].raw = round(rate_dps * 1000 * 2**20 / 360.0)
            deadline = time.monotonic() + 10.0
            seen = 0.0
            while time.monotonic() < deadline:  # 200 deg/s^2: there in 0.05 s real time
                seen = node.sdo[0x606C].raw * 360.0 / 2**20 / 1000
                if abs(seen - rate_dps) < 0.05:
                    break
                time.sleep(0.05)
            assert seen == pytest.approx(rate_dps, abs=0.05)
            node.sdo[0x60FF].raw = 0
            node.state = "SWITCH ON DISABLED"
        finally:
            network.disconnect()
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            _, err = proc.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            raise
    assert proc.returncode == 0, err
    assert "twins stopped" in err
