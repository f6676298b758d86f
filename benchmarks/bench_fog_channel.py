"""Benchmark: the FOG's byte channel alone, a pty against a socket pair (run on demand).

    python benchmarks/bench_fog_channel.py [--mb 400] [--busy]

Moves `--mb` MB from a writer thread to a reader thread the way the FOG twin and driver
do (sims/fog_line.py `_write_all`: non-blocking writes of 1 MB items, poll for room;
drivers/fog.py `_batch`: pyserial's read, then `os.readv` into one 512 kB buffer), once
through a pty opened with pyserial, once through a Unix socket pair with 1 MB buffers.
`--busy` adds a thread that holds the interpreter lock part of the time (numpy on 16384
samples and a pure-Python loop, as the co-simulation's stepping thread does). Prints MB/s
of wall time, the process's user and system CPU, and the paper ladder's FOG bytes
(3.8 GB, 106 M frames of 36 bytes) at that pace.

Why (issue 62): a pty's slave is read through n_tty, whose buffer is 4 kB: every 4 kB a
kernel worker must run (flush_to_ldisc) and wake the reader, which then takes the
interpreter lock back. The paper ladder's 3.8 GB are ~930 k such round trips.
Measured 29 Nov 2026 (this 2-core VM shared with six agents, load 8-14; helper-23): pty
56-72 MB/s, 1.5-2.0 CPU s per 400 MB (user 0.5, system 1.0-1.5); with --busy 20-31 MB/s
(6 MB/s in a variant whose busy thread held the lock longer; with --busy the user time
includes the busy thread's). Socket pair 1650-2300 MB/s, 0.1 CPU s per 400 MB; with --busy
580-1060 MB/s. At 65 MB/s the ladder's FOG bytes alone take 58 s of wall time (the issue's
goal for the whole ladder is 60 s) and ~16 CPU s in the channel; through a socket pair
2-7 s and < 1 CPU s. A pty's slave gives no more a call by other means: os.splice from it
returns 4095 bytes, os.sendfile from it fails with EINVAL (kernel 6.18). In the whole
paper ladder a socket pair instead of the pty saved ~11 s of system time and no wall
time at load 13-34 (benchmarks/bench_ladder.py, 29 Nov 2026): there the channel is
not what sets the pace.
"""

from __future__ import annotations

import argparse
import os
import resource
import select
import socket
import sys
import threading
import time
import tty
from collections.abc import Callable

import numpy as np
import serial

LADDER_FOG_BYTES = 106_000_000 * 36
ITEM_BYTES = 1 << 20
BATCH_BYTES = 1 << 19


def _writer(fd: int, total: int, item: bytes) -> None:
    poller = select.poll()
    poller.register(fd, select.POLLOUT)
    sent = 0
    while sent < total:
        view = memoryview(item)
        while view:
            try:
                view = view[os.write(fd, view):]
            except BlockingIOError:
                poller.poll(50)
        sent += len(item)


def _reader(fd: int, total: int, first: Callable[[], bytes]) -> None:
    buf = bytearray(BATCH_BYTES)
    view = memoryview(buf)
    got = 0
    while got < total:
        head = first()
        size = len(head)
        view[:size] = head
        while size < len(buf):
            try:
                n = os.readv(fd, (view[size:],))
            except BlockingIOError:
                n = None
            if n:
                size += n
                continue
            if not select.select([fd], [], [], 0.0002)[0]:
                break
        got += size


def _busy(stop: threading.Event) -> None:
    x = np.random.default_rng(0).random(16384)
    while not stop.is_set():
        for _ in range(50):
            x = np.cos(x) + 1.0
        y = 0
        for i in range(2000):
            y += i


#: the channels' endpoints, kept open while their threads run
_KEEP: list[object] = []


def _pty(total: int, item: bytes) -> tuple[threading.Thread, threading.Thread]:
    master, slave = os.openpty()
    tty.setraw(slave)
    ser = serial.Serial(os.ttyname(slave), 921600, timeout=0.05)
    os.close(slave)
    os.set_blocking(master, False)
    _KEEP.append(ser)

    def first() -> bytes:
        return bytes(ser.read(max(1, min(ser.in_waiting, BATCH_BYTES))))
    return (threading.Thread(target=_writer, args=(master, total, item)),
            threading.Thread(target=_reader, args=(ser.fileno(), total, first)))


def _socketpair(total: int, item: bytes) -> tuple[threading.Thread, threading.Thread]:
    a, b = socket.socketpair()
    for s in (a, b):
        s.setblocking(False)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1 << 20)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
    _KEEP.extend((a, b))

    def first() -> bytes:
        select.select([b], [], [], 0.05)
        try:
            return b.recv(BATCH_BYTES)
        except BlockingIOError:
            return b""
    return (threading.Thread(target=_writer, args=(a.fileno(), total, item)),
            threading.Thread(target=_reader, args=(b.fileno(), total, first)))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mb", type=int, default=400)
    ap.add_argument("--busy", action="store_true")
    args = ap.parse_args()
    sys.setswitchinterval(0.0005)   # sims/clock.py GIL_SWITCH_S, as in the co-simulation
    total = args.mb << 20
    item = np.random.default_rng(1).integers(0, 256, ITEM_BYTES, dtype=np.uint8).tobytes()
    for name, make in (("pty", _pty), ("socket pair", _socketpair)):
        stop = threading.Event()
        busy = threading.Thread(target=_busy, args=(stop,), daemon=True)
        if args.busy:
            busy.start()
        writer, reader = make(total, item)
        t0, c0 = time.monotonic(), resource.getrusage(resource.RUSAGE_SELF)
        reader.start()
        writer.start()
        reader.join()
        writer.join()
        wall, c1 = time.monotonic() - t0, resource.getrusage(resource.RUSAGE_SELF)
        stop.set()
        rate = total / wall
        print(f"{name:12s} {rate / 1e6:7.0f} MB/s, user {c1.ru_utime - c0.ru_utime:5.2f} s, "
              f"system {c1.ru_stime - c0.ru_stime:5.2f} s for {args.mb} MB "
              f"(busy thread: {args.busy}); the paper ladder's FOG bytes at this pace: "
              f"{LADDER_FOG_BYTES / rate:5.1f} s; load {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
