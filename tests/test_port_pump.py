"""The FOG driver's port pump (drivers/port_pump.py) against a real pty: every byte the
far end writes arrives in order through the pipe, and the pump ends when the far end
hangs up, so the reader sees the end instead of waiting for ever."""

from __future__ import annotations

import os
import select
import subprocess
import sys
import threading
import time
import tty
from pathlib import Path

import numpy as np

from drivers.port_pump import PortPump

ROOT = Path(__file__).resolve().parent.parent


def _read_all(fd: int, n: int, timeout_s: float = 30.0) -> tuple[bytes, bool]:
    """Up to n bytes, and whether the pipe ended (its writer gone) before the timeout."""
    out = bytearray()
    t_end = time.monotonic() + timeout_s
    while len(out) < n and time.monotonic() < t_end:
        if select.select([fd], [], [], 0.5)[0]:
            try:
                got = os.read(fd, 1 << 20)
            except BlockingIOError:
                continue
            if not got:
                return bytes(out), True
            out += got
    return bytes(out), False


def test_every_byte_arrives_in_order_through_the_pump() -> None:
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    # pyserial's settings: VMIN = VTIME = 0, so an empty port reads 0 bytes (not the end)
    attrs = tty.tcgetattr(slave)
    attrs[6][tty.VMIN], attrs[6][tty.VTIME] = 0, 0
    tty.tcsetattr(slave, tty.TCSANOW, attrs)
    pump = PortPump.start(path)
    assert pump is not None and pump.fd is not None
    data = np.random.default_rng(7).integers(0, 256, 8 << 20, dtype=np.uint8).tobytes()

    def write() -> None:
        view = memoryview(data)
        while view:
            view = view[os.write(master, view[:65536]):]
            time.sleep(0.0005 if len(view) % 3 else 0.0)   # gaps: the port runs empty
    w = threading.Thread(target=write)
    w.start()
    try:
        got, _ = _read_all(pump.fd, len(data))
        w.join()
        assert got == data
    finally:
        pump.close()
        pump.close()   # twice is safe
        os.close(slave)
        os.close(master)


def test_the_pump_ends_when_the_far_end_hangs_up() -> None:
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    pump = PortPump.start(path)
    assert pump is not None and pump.fd is not None
    os.write(master, b"last words")
    try:
        time.sleep(0.2)
        os.close(slave)
        os.close(master)   # the twin gone: the port hangs up
        got, ended = _read_all(pump.fd, 1 << 20, timeout_s=10.0)   # until the pipe's end
        assert got == b"last words"
        assert ended, "the pump kept the pipe open after the port hung up"
    finally:
        pump.close()


def test_a_ctrl_c_to_the_terminal_leaves_the_pump_running(tmp_path: Path) -> None:
    """Ctrl-C reaches the whole foreground process group; the bench handles it (stops the
    axes, says "interrupted"), so the pump must not die of it first."""
    script = tmp_path / "group.py"
    script.write_text(
        "import os, select, signal, time, tty\n"
        "from drivers.port_pump import PortPump\n"
        "signal.signal(signal.SIGINT, lambda *a: None)  # a handler, as the bench's (an\n"
        "# ignored SIGINT would be inherited by the pump through exec, hiding the point)\n"
        "os.setpgid(0, 0)                                # a group of its own, as a shell gives\n"
        "m, s = os.openpty(); tty.setraw(s)\n"
        "pump = PortPump.start(os.ttyname(s))\n"
        "time.sleep(0.2)\n"
        "os.killpg(0, signal.SIGINT)                     # the operator's Ctrl-C\n"
        "time.sleep(0.2)\n"
        "os.write(m, b'after ctrl-c')\n"
        "got = b''\n"
        "t_end = time.monotonic() + 5\n"
        "while len(got) < 12 and time.monotonic() < t_end:\n"
        "    if select.select([pump.fd], [], [], 0.2)[0]:\n"
        "        b = os.read(pump.fd, 100)\n"
        "        if not b:\n"
        "            break\n"
        "        got += b\n"
        "print(got.decode())\n"
        "pump.close()\n")
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=30, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.stdout.strip() == "after ctrl-c", done.stdout + done.stderr
