"""`bench sim STAND.yaml` (CONTRACT §1) as a user meets it: started in one process, its
twins driven from another with the clients a user's own script would use (pyvisa on the
printed resource, canopen's BaseNode402 on the printed socketcand bus, pyserial on the
printed pty), and the bench's own Axis driver on the same bus. Nothing here is a mock:
three processes' worth of real channels, every one on 127.0.0.1 or a pty.

The drive line is opened exactly as issue 40 gives it: every word but `node=` is a
`can.Bus` argument, numbers as integers.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import can
import canopen
import pytest
import pyvisa
import serial
from canopen.profiles.p402 import BaseNode402, State402

from drivers.axis import Axis
from drivers.cia402 import DEFAULT_EDS_PATH, State
from drivers.clock import MonotonicClock
from drivers.drive_settings import DriveSettings

ROOT = Path(__file__).resolve().parents[1]
STAND = ROOT / "configs" / "stands" / "sim-two-axis.yaml"
#: how long `bench sim` may take to stop on SIGINT/SIGTERM, its threads included
STOP_LIMIT_S = 10.0

pytestmark = pytest.mark.timeout(120)


def bus_kwargs(line: str) -> dict[str, Any]:
    """Issue 40's recipe, word for word: the `can.Bus` arguments of a drive line."""
    return {k: int(v) if v.isdigit() else v
            for k, v in (x.split("=") for x in line.split()[2:] if not x.startswith("node="))}


def wait_for(check: Callable[[], bool], timeout_s: float, every_s: float = 0.05) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if check():
            return True
        time.sleep(every_s)
    return check()


class SimProcess:
    """`bench sim` in a process of its own; its printed lines by (axis, kind)."""

    def __init__(self, stand: Path = STAND) -> None:
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        self.proc = subprocess.Popen([sys.executable, "-m", "bench", "sim", str(stand)],
                                     cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True, env=env)
        self.lines: dict[tuple[str, str], str] = {}

    def read_lines(self, n: int, timeout_s: float = 60.0) -> dict[tuple[str, str], str]:
        deadline = time.monotonic() + timeout_s
        assert self.proc.stdout is not None
        while len(self.lines) < n and time.monotonic() < deadline:
            line = self.proc.stdout.readline()
            if not line:
                break
            axis, kind, *_ = line.split()
            self.lines[(axis, kind)] = line.strip()
        return self.lines

    def stop(self, sig: signal.Signals = signal.SIGINT) -> tuple[int, str, float]:
        """Signal it; (exit status, stderr, seconds it took to end)."""
        t0 = time.monotonic()
        self.proc.send_signal(sig)
        try:
            _, err = self.proc.communicate(timeout=STOP_LIMIT_S)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.communicate()
            raise AssertionError(
                f"bench sim still running {STOP_LIMIT_S} s after {sig.name}") from None
        return self.proc.returncode, err, time.monotonic() - t0


@pytest.fixture(scope="module")
def sim() -> Iterator[SimProcess]:
    s = SimProcess()
    try:
        found = s.read_lines(6)
        assert set(found) == {(a, k) for a in ("outer", "inner")
                              for k in ("counter", "fog", "drive")}, found
        yield s
    finally:
        if s.proc.poll() is None:
            s.stop()


def test_drive_lines_name_every_bus_argument_on_loopback(sim: SimProcess) -> None:
    outer, inner = sim.lines[("outer", "drive")], sim.lines[("inner", "drive")]
    kw = bus_kwargs(outer)
    assert kw["interface"] == "socketcand" and kw["host"] == "127.0.0.1"
    assert isinstance(kw["port"], int) and kw["channel"] == "bench"
    assert outer.split()[-1] == "node=2" and inner.split()[-1] == "node=3"
    assert bus_kwargs(inner) == kw          # the stand shares one bus between its axes
    with can.Bus(**kw) as bus:              # the recipe opens it as it stands
        hb = bus.recv(5.0)
        while hb is not None and hb.arbitration_id not in (0x702, 0x703):
            hb = bus.recv(5.0)
        assert hb is not None, "no drive heartbeat on the printed bus"


def test_counter_and_fog_from_another_process(sim: SimProcess) -> None:
    rm = pyvisa.ResourceManager("@py")
    inst = rm.open_resource(sim.lines[("outer", "counter")].split()[2], read_termination="\n",
                            write_termination="\n", timeout=5000)
    try:
        assert "53230A" in inst.query("*IDN?")
        assert inst.query("SYST:ERR?").startswith("+0")
    finally:
        inst.close()
    with serial.Serial(sim.lines[("outer", "fog")].split()[2], 921600, timeout=2.0) as fog:
        assert b"\xfe\x81\xff\x55" in fog.read(400)   # KVH format A header


def _velocity_units(node: BaseNode402) -> float:
    return float(node.sdo[0x606C].raw)


def test_base_node_402_alone_drives_the_outer_axis(sim: SimProcess) -> None:
    """canopen's BaseNode402 with the shipped EDS and nothing of ours: NMT, the CiA 402
    state machine through its RPDO controlword (a client on socketcand does not hear its
    own frames, so canopen sends them), profile velocity at 10 % of 0x607F, halt, quick
    stop to the state 0x605A names, and back to OPERATION ENABLED."""
    line = sim.lines[("outer", "drive")]
    node_id = int(line.split()[-1].split("=")[1])
    network = canopen.Network()
    network.connect(**bus_kwargs(line))
    try:
        node = BaseNode402(node_id, str(DEFAULT_EDS_PATH))
        network.add_node(node)
        node.sdo.RESPONSE_TIMEOUT = 2.0
        node.nmt.state = "PRE-OPERATIONAL"
        node.setup_402_state_machine(read_pdos=True)   # its PDO maps, read by SDO
        node.nmt.state = "OPERATIONAL"
        node.nmt.wait_for_heartbeat(5.0)
        assert wait_for(lambda: node.nmt.state == "OPERATIONAL", 5.0)
        node.op_mode = "PROFILED VELOCITY"
        node.sdo[0x60FF].raw = 0
        node.state = "OPERATION ENABLED"
        assert node.state == "OPERATION ENABLED"
        # profile velocity at 10 % of the drive's max profile velocity 0x607F
        target = int(node.sdo[0x607F].raw) // 10
        assert target > 0
        node.sdo[0x60FF].raw = target
        assert wait_for(lambda: abs(_velocity_units(node) - target) <= 0.05 * target, 20.0), \
            f"velocity {_velocity_units(node)} against {target}"
        # halt (controlword bit 8): to rest, still OPERATION ENABLED
        node.controlword = State402.CW_OPERATION_ENABLED | 0x100
        assert wait_for(lambda: abs(_velocity_units(node)) <= 0.01 * target, 20.0)
        assert node.state == "OPERATION ENABLED"
        node.controlword = State402.CW_OPERATION_ENABLED
        assert wait_for(lambda: abs(_velocity_units(node) - target) <= 0.05 * target, 20.0)
        # quick stop: option code 0x605A decides where it ends (CiA 402: 1-4 switch on
        # disabled once stopped, 5-8 stay in quick stop active)
        code = int(node.sdo[0x605A].raw)
        expected = "QUICK STOP ACTIVE" if 5 <= code <= 8 else "SWITCH ON DISABLED"
        node.controlword = State402.CW_QUICK_STOP
        assert wait_for(lambda: node.state == expected, 20.0), (code, node.state)
        assert wait_for(lambda: abs(_velocity_units(node)) <= 0.01 * target, 20.0)
        node.sdo[0x60FF].raw = 0
        node.state = "OPERATION ENABLED"
        assert node.state == "OPERATION ENABLED"
        node.state = "SWITCH ON DISABLED"
    finally:
        network.disconnect()


def test_the_bench_axis_driver_drives_a_bench_sim_drive(sim: SimProcess) -> None:
    """drivers/axis.py over socketcand, as a stand pointing at `bench sim` opens it:
    enable, a velocity, its safe stop."""
    kw = bus_kwargs(sim.lines[("outer", "drive")])
    interface, channel = kw.pop("interface"), kw.pop("channel")
    with Axis("outer", DriveSettings(interface=interface, channel=channel, **kw, node_id=2,
                                     max_rate_dps=400.0, max_accel_dps2=200.0,
                                     heartbeat_ms=200, watchdog_ms=1500),
              clock=MonotonicClock()) as ax:
        assert ax.state is State.OPERATION_ENABLED
        ax.set_rate(20.0)
        assert wait_for(lambda: abs(ax.rate_dps - 20.0) < 0.2, 20.0), ax.rate_dps
        assert ax.safe_stop() == []         # ramped to zero, then disabled
        assert abs(ax.rate_dps) < 0.01
        # the latest TPDO's statusword (the next one after the disable)
        assert wait_for(lambda: ax.state is State.SWITCH_ON_DISABLED, 5.0), ax.state


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_bench_sim_stops_promptly(sig: signal.Signals) -> None:
    s = SimProcess()
    assert len(s.read_lines(6)) == 6
    kw = bus_kwargs(s.lines[("outer", "drive")])
    with can.Bus(**kw) as bus:          # a client still connected when it stops
        bus.recv(1.0)
        status, err, took_s = s.stop(sig)
    assert status == 0, err
    assert "twins stopped" in err
    assert took_s < STOP_LIMIT_S
    print(f"bench sim stopped {took_s:.2f} s after {sig.name}")


def _real_stand(sim: SimProcess, path: Path, counter_extra: str = "") -> Path:
    """A stand file without a `sim:` block whose outer axis is `bench sim`'s."""
    kw = bus_kwargs(sim.lines[("outer", "drive")])
    counter = sim.lines[("outer", "counter")].split()[2]
    fog = sim.lines[("outer", "fog")].split()[2]
    path.write_text(
        "stand: {maker: Simulated Tables Ltd, model: ST-2A, serial: SIM-0001}\n"
        "axes:\n"
        "  table:\n"
        f"    drive: {{interface: {kw['interface']}, host: '{kw['host']}', port: {kw['port']},\n"
        f"             channel: {kw['channel']}, node_id: 2, max_rate_dps: 400,\n"
        "             max_accel_dps2: 200, counts_per_rev: 1048576, unit_factors: read}\n"
        f"    counter: {{resource: '{counter}', model: keysight-53230a,{counter_extra}\n"
        "               reference: internal, time_tie: {source: host-clock}}\n"
        f"    fog: {{port: '{fog}', baudrate: 921600, format: kvh-a, axis: z,\n"
        "           rate_hz: 1000, units: deg/s, configure: set}\n")
    return path


def test_a_real_stand_pointing_at_bench_sim(sim: SimProcess, tmp_path: Path) -> None:
    """A stand file without a `sim:` block whose addresses are `bench sim`'s is a real
    stand to the bench: the real-stand rules apply (a time tie, a trigger level, the drive's
    factor group read), and `bench devices` opens all three instruments over their channels
    and reads their identities (the twins' serials)."""
    stand = _real_stand(sim, tmp_path / "pointed-at-bench-sim.yaml")
    bench = [sys.executable, "-m", "bench"]
    refused = subprocess.run([*bench, "devices", str(stand)], cwd=ROOT, capture_output=True,
                             text=True, timeout=60)
    assert refused.returncode == 3 and "level_v" in refused.stderr, refused.stderr
    stand = _real_stand(sim, stand, " level_v: 2.5,")
    valid = subprocess.run([*bench, "validate", str(stand)], cwd=ROOT, capture_output=True,
                           text=True, timeout=60)
    assert valid.returncode == 0, valid.stdout + valid.stderr
    out = subprocess.run([*bench, "devices", str(stand)], cwd=ROOT, capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    rows = {line.split()[1]: line for line in out.stdout.splitlines()
            if line.startswith("table ")}
    assert "serial 41001" in rows["drive"]              # the twin's 0x1018:4
    assert "MY62000117" in rows["counter"]              # its *IDN? serial
    assert "format kvh-a" in rows["fog"]


def _register_holding(tmp_path: Path, serial: str) -> Path:
    """A lab file naming an SQLite register whose inventory holds the counter `serial`
    in date (issue 54: a real stand starts only under the lab's register)."""
    import datetime as dt

    from bench.app.register import Register
    from tests.registers import lab_file, password, sqlite_register

    url = sqlite_register(tmp_path / "register")
    with Register.open(url, migrate=False) as reg:
        quality = reg.authenticate("Q. Manager", password("Q. Manager"), "quality")
        reg.add_equipment(quality, serial, "Keysight 53230A", "C-2026-1234", "Cal Lab",
                          dt.date.today() + dt.timedelta(days=200))
    return lab_file(tmp_path / "lab", url)


def test_a_real_stand_naming_another_counter_is_refused_before_anything_moves(
        sim: SimProcess, tmp_path: Path) -> None:
    """Issue 41: the stand states counter MY59001234, *IDN? answers MY62000117 (a swapped
    counter): exit 2 naming both, and no step ran."""
    stand = _real_stand(sim, tmp_path / "stand.yaml",
                        " level_v: 2.5, serial: MY59001234,")
    proc = tmp_path / "ladder.yaml"
    proc.write_text(f"procedure: rate-ladder\ntitle: swapped counter\nstand: {stand}\n"
                    "turns: 2\nstatic_record_s: 2\nprompts: false\nmains_hz: 50\n"
                    "axes:\n  table:\n    rates_dps: [50]\n")
    lab = _register_holding(tmp_path, "MY59001234")    # a real stand runs under a register
    out = subprocess.run([sys.executable, "-m", "bench", "run", str(proc), "--yes", "--out",
                          str(tmp_path / "runs"), "--lab", str(lab)], cwd=ROOT,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 2, out.stdout + out.stderr
    assert ("axes.table.counter.serial: the stand file states serial MY59001234, the "
            "instrument reports MY62000117 (*IDN?)") in out.stderr, out.stderr
    events = [json.loads(line) for run in (tmp_path / "runs").iterdir() if run.is_dir()
              for line in (run / "events.jsonl").read_text().splitlines()]
    kinds = [e["event"] for e in events]
    assert "refused" in kinds and "step_start" not in kinds, kinds
