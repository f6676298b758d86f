"""The FOG twin's serial line: the pty, the writer thread, the output queue, and the
twin's part in the stand's clock (the co-simulation's steps or the paced clock's pacer),
as sims/fog_twin.py's docstring describes under "Time" and "Two details of real ports".
"""

from __future__ import annotations

import errno
import math
import os
import select
import threading
import time
import tty
from collections import deque
from collections.abc import Callable

from drivers.kvh_config import WORDS
from sims.clock import SteppedClock
from sims.fog_faults import Hold
from sims.fog_settings import FogSettings

_TICK_S = 0.002            # real seconds between looks at the clock when idle
_OPEN_SETTLE_S = 0.05      # real seconds for pyserial to configure and flush after open
_WRITE_POLL_MS = 50
#: on a stepped clock, real ms the idle writer waits for frames or a command before it
#: looks again anyway (a safety net: both wake it at once, `_idle`)
_IDLE_MS = 50
#: on a stepped clock, real seconds between looks at a port nobody has open (a reader
#: opening it is answered at most this late, once; 2 ms ticks of the twin of the axis not
#: under test were ~500 wake-ups a real second, issue 62)
_UNREAD_TICK_S = 0.02
#: on a stepped clock, bytes the channel may hold between the steps of one wait (queued
#: in the twin, in the pty, not yet decoded): the twin encodes while the driver decodes
_LEAD_BYTES = 4 << 20


class FogLine(FogSettings):
    """The pty the driver reads, and the thread that writes the queued frames to it."""

    #: set by FogTwin.__init__ (sims/fog_twin.py)
    _inbuf: bytearray
    commands: list[str]
    _queue: deque[tuple[bytes | memoryview, int] | Hold]
    _sent_n: int
    _reading: bool
    _slow: tuple[float, float, int] | None
    _qlock: threading.Lock
    _master: int | None
    _thread: threading.Thread | None
    _stop: threading.Event
    _wake: threading.Event
    #: a pipe `_rouse` writes to, so the idle writer can wait on it beside the port
    _wake_fds: tuple[int, int] | None
    #: the writer sleeps on the wake pipe (set by `_idle`, read by `_rouse`)
    _asleep: bool
    _gate_open: bool
    _queued_bytes: int
    _stepped: bool
    _leave: Callable[[], None] | None
    _presence: select.poll | None
    path: str | None
    bytes_written: int

    def start(self) -> str:
        """Open the pty and start writing; returns the slave path for the driver."""
        if self._thread is not None:
            raise RuntimeError("FOG twin already started")
        master, slave = os.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        os.close(slave)  # a reader opening the path is then seen as POLLHUP clearing
        os.set_blocking(master, False)
        self._master = master
        if self._stepped:
            r, w = os.pipe()
            os.set_blocking(r, False)
            os.set_blocking(w, False)
            self._wake_fds = (r, w)
        self._presence = select.poll()
        self._presence.register(master, select.POLLOUT)
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=f"fog-twin-{self.axis.name}",
                                        daemon=True)
        self._thread.start()
        if self._stepped:
            # drained when the driver reads (sims/clock.py settle_channel), not at the end
            # of every wait: the drives' settles and turn timing read no FOG sample
            self._leave = self._stepped_clock.join(self, drained_on_read=self.path)
        return self.path

    @property
    def _stepped_clock(self) -> SteppedClock:
        """The co-simulation's clock: reached only on a stepped stand (self._stepped)."""
        assert isinstance(self.clock, SteppedClock)
        return self.clock

    def next_event_s(self, t_s: float) -> float:
        return math.inf  # frames follow the stand's samples; a hold ends with the clock

    def advance(self, t_s: float) -> None:
        self.axis.advance_to(t_s)

    def settled(self, t_s: float, final: bool) -> bool:
        """Frames up to t_s out and decoded (final), or within the lead of it."""
        if self._stop.is_set() or self.path is None \
                or not self._stepped_clock.has_consumer(self.path) or self.config_mode:
            return True
        if not self._gate_open:
            return False
        with self._qlock:
            head = self._queue[0] if self._queue else None
            queued = self._queued_bytes
        due = head is not None and (not isinstance(head, Hold) or head.until_s <= t_s)
        backlog = self._stepped_clock.backlog(self.path)
        if final:
            return not due and backlog == 0
        return queued + backlog <= _LEAD_BYTES

    def delivered_s(self) -> float:
        """The clock's pacer: stand time up to which frames are out on the port.

        A twin nobody reads (no reader yet, or the reader gone) paces nothing (inf), and a
        stall injected on purpose holds the frames, not the clock.
        """
        if not self._reading or self._stop.is_set() or self.config_mode:
            return math.inf   # (Configuration Mode: the unit sends nothing to keep up with)
        with self._qlock:
            head = self._queue[0] if self._queue else None
        sent_s = (self._sent_n - 1) / self.rate_hz
        return max(head.until_s, sent_s) if isinstance(head, Hold) else sent_s

    def _rouse(self) -> None:
        """Frames queued (or the twin stopping): the writer need not wait a tick. The
        wake pipe is written only while the writer sleeps on it (`_asleep`): a write per
        encoded chunk gave the interpreter lock away each time, and taking it back cost the
        stepping thread ~0.75 ms a chunk behind the readers' decoding (issue 62). The
        writer says it sleeps before it looks at the queue a last time, so frames queued
        after that look find it asleep and wake it."""
        self._wake.set()
        if self._wake_fds is not None and (self._asleep or self._stop.is_set()):
            try:
                os.write(self._wake_fds[1], b"\0")
            except OSError:   # the pipe full (the writer is awake) or closed (stopped)
                pass

    def _idle(self, idle: select.poll | None) -> None:
        """Nothing to write: wait for frames queued (`_rouse`), a command from the driver,
        or a tick. On a stepped clock nothing else brings the writer work, so it sleeps on
        the port and the wake pipe instead of looking every 2 ms (two twins: ~1000 wake-ups
        a real second, each taking the interpreter lock, issue 62); a port nobody has open
        reports a hang-up at once, and there it looks every `_UNREAD_TICK_S`."""
        if idle is None or self._wake_fds is None:
            self._wake.wait(_TICK_S)
            self._wake.clear()
            return
        self._asleep = True
        try:
            with self._qlock:   # frames queued before it said so (a hold waits for time)
                due = bool(self._queue) and not isinstance(self._queue[0], Hold)
            events = [] if due else idle.poll(_IDLE_MS)
        finally:
            self._asleep = False
        if any(fd == self._master and ev & select.POLLHUP for fd, ev in events):
            self._wake.wait(_UNREAD_TICK_S)
        self._wake.clear()
        try:
            os.read(self._wake_fds[0], 4096)
        except OSError:
            pass

    def _reader_present(self, poller: select.poll) -> bool:
        return not any(ev & select.POLLHUP for _, ev in poller.poll(0))

    def _nobody_reads(self) -> bool:
        """No reader has the port: the chunk's frames would go nowhere (module docstring)."""
        if self._stop.is_set():
            return False
        if self._stepped:   # set by the driver between clock steps: the same on every run
            return self.path is None or not self._stepped_clock.has_consumer(self.path)
        return self._presence is not None and not self._reader_present(self._presence)

    def _run(self) -> None:
        assert self._master is not None and self.path is not None  # set by start()
        poller = select.poll()
        poller.register(self._master, select.POLLOUT)
        seen: float | None = None
        while not self._stop.is_set():  # the gate: a reader settled, and a running clock
            self._serve_commands()
            if seen is None and self._reader_present(poller):
                seen = time.monotonic()
                self._reading = True
            if self._stepped:
                # the driver says when it records (after its configuration dialogue and
                # the flush that ends it): frames written before would be flushed, and
                # the first frame read would not be stand sample 0
                if seen is not None and self._stepped_clock.has_consumer(self.path):
                    break
            elif seen is not None and time.monotonic() - seen >= _OPEN_SETTLE_S \
                    and getattr(self.clock, "running", True):
                break
            if self._stepped and seen is None:   # nobody has the port open yet
                self._wake.wait(_UNREAD_TICK_S)
                self._wake.clear()
                continue
            time.sleep(_TICK_S)
        self._gate_open = True
        idle = None
        if self._stepped:
            self._stepped_clock.poke()
            if self._wake_fds is not None:
                idle = select.poll()
                idle.register(self._master, select.POLLIN)
                idle.register(self._wake_fds[0], select.POLLIN)
        while not self._stop.is_set():
            self._serve_commands(None if self._stepped else poller)
            if self.config_mode:  # no binary output in Configuration Mode (ICD 3.3)
                time.sleep(_TICK_S)
                continue
            if not self._stepped:  # a paced clock: the twin follows it (stepped: advance())
                self.axis.advance_to(self.clock.now())
            if not self._drain(poller):
                self._idle(idle)

    def _serve_commands(self, poller: select.poll | None = None) -> None:
        """Answer the lines received. With `poller` (the stream running on a paced clock)
        the frames due up to `=CONFIG,1` go out before its answer: the unit streamed
        until then (on a stepped clock the clock's steps release the samples)."""
        assert self._master is not None
        try:
            data = os.read(self._master, 4096)
        except (BlockingIOError, OSError):
            return
        self._inbuf.extend(data)
        while True:
            cut = [i for i in (self._inbuf.find(b"\r"), self._inbuf.find(b"\n")) if i >= 0]
            if not cut:
                return
            i = min(cut)
            line = bytes(self._inbuf[:i]).decode("ascii", "replace").strip()
            del self._inbuf[:i + 1]
            if line:
                self.commands.append(line)
                now_s = None
                if poller is not None and not self.config_mode \
                        and line.upper().replace(" ", "") == f"={WORDS.config},1":
                    now_s = self.clock.now()
                    self.axis.advance_to(now_s)
                    self._drain(poller)
                reply = self._answer(line, now_s)
                if reply is not None:  # after the frames already queued in the port
                    self._write_reply((reply + "\r\n").encode("ascii"))

    def _write_reply(self, data: bytes) -> None:
        """Write a reply whole, waiting while the port's buffer is full (a reader still
        busy with the frames sent before Configuration Mode)."""
        assert self._master is not None
        view = memoryview(data)
        deadline = time.monotonic() + 5.0
        while view and not self._stop.is_set() and time.monotonic() < deadline:
            try:
                view = view[os.write(self._master, view):]
            except BlockingIOError:
                select.select([], [self._master], [], _WRITE_POLL_MS / 1000)
            except OSError:
                return  # no reader: the reply is lost, as on a cable nobody listens to

    def _drain(self, poller: select.poll) -> bool:
        """Write what is due; False if there was nothing to write."""
        wrote = False
        while not self._stop.is_set():
            # the clock's time is read before the queue's lock is taken: the paced clock
            # calls delivered_s (which takes that lock) while it holds its own
            now_s = self.clock.now()
            with self._qlock:
                if not self._queue:
                    return wrote
                item = self._queue.popleft()
                if isinstance(item, Hold):
                    if now_s < item.until_s:
                        self._queue.appendleft(item)
                        return wrote
                    continue
                self._queued_bytes -= len(item[0])
                if self._stepped and self.path is not None:
                    self._stepped_clock.sent(self.path, len(item[0]))  # counted before it can be read
            data, n_end = item
            self._write_all(data, poller)
            self._sent_n = max(self._sent_n, n_end)
            self._throttle()
            wrote = True
        return wrote

    def _write_all(self, data: bytes | memoryview, poller: select.poll) -> None:
        view = memoryview(data)
        while view and not self._stop.is_set():
            try:
                k = self._write_some(view)
                self._reading = True
                view = view[k:]
                self.bytes_written += k
            except BlockingIOError:
                events = poller.poll(_WRITE_POLL_MS)
                gone = any(ev & select.POLLHUP for _, ev in events)
                self._reading = not gone  # a reader gone paces nothing
                if gone:
                    time.sleep(_WRITE_POLL_MS / 1000)  # reader gone: keep the frames
            except OSError as e:
                if e.errno != errno.EIO:
                    raise
                time.sleep(_WRITE_POLL_MS / 1000)

    def _write_some(self, view: memoryview) -> int:
        """Write to the port: on a stepped clock all of `view` in one call, the kernel
        handing it to the reader a pty's few kB at a time while this thread waits without
        the interpreter lock (written piece by piece, each piece took the lock back, and a
        bench thread computing the stand held it: the channel moved only while the bench
        waited, issue 62). The twin sends only while its driver reads (a channel counted
        open), and a driver that closes the port ends the call (EIO). Elsewhere as much as
        the port takes now (the paced clock's writer watches for a reader gone)."""
        assert self._master is not None
        if not self._stepped:
            return os.write(self._master, view)
        os.set_blocking(self._master, True)
        try:
            return os.write(self._master, view)
        finally:
            os.set_blocking(self._master, False)

    def slow_down(self, frames_per_real_s: float | None) -> None:
        """From now on send at most this many frames a real second (None: no limit).

        A twin slowed on purpose stands for a loaded machine or a slow link: the paced
        clock must follow it (sims/clock.py), never leave the FOG's reader waiting.
        """
        if frames_per_real_s is not None and not frames_per_real_s > 0:
            raise ValueError(f"frames_per_real_s must be > 0, got {frames_per_real_s}")
        self._slow = (None if frames_per_real_s is None
                      else (float(frames_per_real_s), time.monotonic(), self._sent_n))

    def _throttle(self) -> None:
        slow = self._slow
        if slow is not None:
            rate, since, sent0 = slow
            time.sleep(max(since + (self._sent_n - sent0) / rate - time.monotonic(), 0.0))
