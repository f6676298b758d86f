"""What a session owns ends with it: a set-up failure and a killed bench (issue 25).

Both go through the real CLI in a subprocess. The set-up failure is a stand with no `sim:`
block whose drive is absent from its (python-can virtual) bus: nothing answers, as on a
bench whose drive is unpowered. The kill is a SIGKILL of `bench run` on the twins while
the pair analysis worker lives.
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.conftest import CONFIGS, ROOT
from tests.registers import lab_file, sqlite_register

NO_DRIVE_STAND = """\
stand: {maker: Test, model: T1, serial: "S-1"}
axes:
  outer:
    drive:   {interface: virtual, channel: no-drive-here, node_id: 2, max_rate_dps: 400,
              max_accel_dps2: 200, unit_factors: read}
    counter: {resource: "TCPIP0::127.0.0.1::1::SOCKET", model: keysight-53230a, level_v: 2.5,
              reference: external, timebase_limit_rel: 1.0e-9,
              time_tie: {source: fog-sync, sync_period_s: 5.0, latency_s: 2.0e-6,
                         latency_u_s: 2.0e-7}}
    fog:     {port: /dev/null-fog, baudrate: 921600, format: kvh-a, axis: z, rate_hz: 1000,
              units: deg/s}
"""

ONE_RATE = """\
procedure: rate-ladder
stand: stand.yaml
turns: 2
axes:
  outer: {rates_dps: [10]}
tolerance:
  rate_error:
    - {rel: 1.0e-5}
"""


def test_a_set_up_failure_exits_3_names_its_cause_and_prints_the_run_directory_last(
        tmp_path: Path) -> None:
    (tmp_path / "stand.yaml").write_text(NO_DRIVE_STAND)
    (tmp_path / "p.yaml").write_text(ONE_RATE)
    # a real stand runs only under the lab's register (issue 54)
    lab = lab_file(tmp_path / "lab", sqlite_register(tmp_path / "register"))
    out = subprocess.run([sys.executable, "-m", "bench", "run", str(tmp_path / "p.yaml"),
                          "--yes", "--out", str(tmp_path / "runs"), "--lab", str(lab)],
                         cwd=ROOT, text=True, capture_output=True, timeout=120)
    assert out.returncode == 3, out.stdout + out.stderr
    assert "Traceback" not in out.stderr, out.stderr
    # the first line the operator reads is the cause, naming the axis and the drive
    first = out.stderr.strip().splitlines()[0]
    assert first.startswith("Aborted: while setting up the bench"), out.stderr
    assert "drive node 2" in first and "no-drive-here" in first, first
    run_dir = Path(out.stdout.strip().splitlines()[-1])
    assert run_dir.parent == tmp_path / "runs" and (run_dir / "events.jsonl").is_file()
    assert "history section was left out" not in out.stderr, out.stderr


def _descendants(pid: int) -> set[int]:
    """Every live process below `pid`, from /proc (ppid links)."""
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        ppid = int(stat.rsplit(")", 1)[1].split()[1])
        children.setdefault(ppid, []).append(int(entry.name))
    found: set[int] = set()
    todo = [pid]
    while todo:
        for c in children.get(todo.pop(), []):
            if c not in found:
                found.add(c)
                todo.append(c)
    return found


def _alive(pid: int) -> bool:
    """Running, sleeping or stopped: a zombie (exited, not yet reaped) counts as gone."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


@pytest.mark.timeout(240)
def test_sigkill_mid_analysis_leaves_no_process_of_the_run_alive(tmp_path: Path) -> None:
    """The analysis worker watches the bench: a SIGKILLed bench leaves nothing behind,
    and a pipe reading the bench's output (`bench run | tee log`) sees its end."""
    proc = tmp_path / "two-pairs.yaml"
    proc.write_text(
        f"procedure: rate-ladder\nstand: {CONFIGS / 'stands' / 'sim-two-axis.yaml'}\n"
        "turns: 4\nsequence: '+-'\nstatic_record_s: 2\nharmonics: 1\nprompts: false\n"
        "axes:\n  outer: {rates_dps: [60, 90, 120]}\n")
    p = subprocess.Popen([sys.executable, "-m", "bench", "run", str(proc), "--yes",
                          "--out", str(tmp_path / "runs")], cwd=ROOT,
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 180
        workers: set[int] = set()
        while time.monotonic() < deadline and p.poll() is None:
            # the analysis worker is forked by the fork server (bench/core/engine.py):
            # two processes with its command line, the server and the worker
            workers = {c for c in _descendants(p.pid)
                       if b"multiprocessing.forkserver" in Path(f"/proc/{c}/cmdline")
                       .read_bytes()}
            if len(workers) >= 2:
                break
            time.sleep(0.05)
        assert p.poll() is None, "the run ended before its analysis worker started"
        assert len(workers) >= 2, "no analysis worker seen"
        family = _descendants(p.pid)
        os.kill(p.pid, signal.SIGKILL)
        p.wait(timeout=10)
        assert p.stdout is not None
        t0 = time.monotonic()
        eof = False  # EOF comes when no process holds the bench's stdout open any more
        while not eof and time.monotonic() - t0 < 10:
            if select.select([p.stdout], [], [], 0.2)[0]:
                eof = not os.read(p.stdout.fileno(), 65536)
        assert eof, "the bench's stdout is still held open 10 s after the kill"
        time.sleep(max(0.0, 10 - (time.monotonic() - t0)))
        left = sorted(c for c in family if _alive(c))
        assert not left, [Path(f"/proc/{c}/cmdline").read_bytes() for c in left]
    finally:
        if p.poll() is None:
            p.kill()
