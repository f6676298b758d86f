"""The FOG driver's port pump (drivers/port_pump.py) against a real pty: every byte the
far end writes arrives in order through the pipe, and the pump ends when the far end
hangs up, so the reader sees the end instead of waiting for ever."""

from __future__ import annotations

import os
import select
import threading
import time
import tty

import numpy as np

from drivers.port_pump import PortPump


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
