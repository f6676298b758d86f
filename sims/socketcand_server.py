"""A socketcand server on 127.0.0.1 for the twins' CAN buses: a bus between processes that
never leaves the machine.

Inside one process the twins and the bench share python-can's `virtual` bus. A script in
another process (`bench sim`'s users, canopen's BaseNode402, the bench's own driver
pointed at `bench sim`) needs a channel between processes. socketcand is the one real
labs use for that: a daemon that serves a host's CAN buses over TCP in a text protocol
that python-can's `socketcand` interface, Kayak and socketcandcl speak. This module is
that daemon's protocol in front of the `virtual` channels of this process.

What it follows (linux-can/socketcand, doc/protocol.md, and the daemon's own
src/state_nobus.c and src/state_raw.c where the two differ):

- On connect the server greets `< hi >`; `< open BUS >` answers `< ok >` (mode BCM), or
  `< error could not open bus >` and closes the connection for a bus it does not serve.
- `< rawmode >` answers `< ok >`; from then on every frame on the bus goes to the client
  as `< frame ID SECS.USECS DATA >`: ID `%03X` (standard) or `%08X` (extended), DATA the
  bytes as `%02X` run together, empty for a zero-length frame (a SYNC is
  `< frame 080 1.000000  >`: the empty data token is kept, as the daemon's sprintf does,
  and python-can's parser needs it). `< bcmmode >` answers `< ok >` and stops them.
- `< send ID LEN B0 B1 ... >` (bytes in hex, in BCM and raw mode alike) puts a frame on
  the bus; an 8-digit ID is extended. A malformed one is ignored, as by the daemon.
  `< sendrtr ID DLC >` sends a remote frame. `< echo >` is echoed.
- BCM jobs (`add`, `update`, `delete`, `subscribe`, `filter`, `muxfilter`) and the
  control and ISO-TP modes are not served: `< error unknown command >`. Nothing here
  needs them; a client that does learns so at once.

As on a real bus, a client sees every frame but its own: frames from the twins (the
server's own `virtual` bus instance, which python-can does not echo its sends back to)
and from every other client of the same bus.

python-can's client reads each handshake reply with one `recv` and compares it exactly,
so a frame must not share a segment with the `< ok >` to `< rawmode >`. A client's frames
are therefore held from its rawmode reply until it sends its first command (it has read
the reply by then) or `HANDSHAKE_HOLD_S` has passed, and then delivered in order; nothing
is dropped. Its parser also needs each frame whole, which TCP does not promise: each line
goes out in one `sendall` (TCP_NODELAY), and the client's buffer takes partial lines.
"""

from __future__ import annotations

import contextlib
import logging
import queue
import re
import socket
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import can

log = logging.getLogger(__name__)

#: the only address the server binds: a twin's bus never leaves the machine
LOOPBACK_HOST = "127.0.0.1"
#: socketcand's limit on a bus name (doc/protocol.md, "Mode NO_BUS")
MAX_BUS_NAME = 16
#: how long a new raw-mode client's frames wait for its first command (module docstring)
HANDSHAKE_HOLD_S = 0.5
#: frames queued for one client that does not read: beyond it the oldest are dropped and
#: counted, as a CAN controller's receive FIFO overflows (memory stays bounded)
CLIENT_QUEUE_FRAMES = 65536

_COMMAND = re.compile(r"<[^<>]*>")
_HEX_ID = re.compile(r"^[0-9A-Fa-f]{1,8}$")

HI = "< hi >"
OK = "< ok >"
ERROR_OPEN = "< error could not open bus >"
ERROR_UNKNOWN = "< error unknown command >"


def frame_line(msg: can.Message) -> str:
    """A received frame in the daemon's raw-mode format (src/state_raw.c)."""
    t = msg.timestamp if msg.timestamp else time.time()
    secs = int(t)
    usecs = min(int(round((t - secs) * 1e6)), 999_999)
    ident = (f"{msg.arbitration_id & 0x1FFFFFFF:08X}" if msg.is_extended_id
             else f"{msg.arbitration_id & 0x7FF:03X}")
    if msg.is_remote_frame:      # doc/protocol.md "RTR frame transmission"
        return f"< rtr {ident} {secs}.{usecs:06d} {msg.dlc} >"
    return f"< frame {ident} {secs}.{usecs:06d} {bytes(msg.data).hex().upper()} >"


def parse_send(command: str) -> can.Message | None:
    """`< send ID LEN B0 ... >` or `< sendrtr ID DLC >` as a message; None if malformed
    (the daemon's sscanf check: 2 + LEN items, LEN <= 8)."""
    tokens = command[1:-1].split()
    if len(tokens) < 3 or tokens[0] not in ("send", "sendrtr"):
        return None
    ident, rest = tokens[1], tokens[2:]
    if not _HEX_ID.match(ident):
        return None
    try:
        length = int(rest[0], 16)       # <= 8: decimal and hex agree (python-can sends %X)
        data = bytes(int(b, 16) for b in rest[1:])
    except ValueError:
        return None
    extended = len(ident) == 8
    can_id = int(ident, 16)
    if length > 8 or can_id > (0x1FFFFFFF if extended else 0x7FF):
        return None
    if tokens[0] == "sendrtr":
        if data:
            return None
        return can.Message(arbitration_id=can_id, is_extended_id=extended,
                           is_remote_frame=True, dlc=length)
    if len(data) != length or any(b > 0xFF for b in data):
        return None
    return can.Message(arbitration_id=can_id, is_extended_id=extended, data=data)


@dataclass(eq=False)
class _Client:
    sock: socket.socket
    peer: str
    bus: str | None = None
    raw: bool = False
    released: bool = True
    raw_since: float = 0.0
    held: deque[str] = field(default_factory=deque)
    out: queue.Queue[str | None] = field(
        default_factory=lambda: queue.Queue(maxsize=CLIENT_QUEUE_FRAMES))
    dropped: int = 0
    lock: threading.Lock = field(default_factory=threading.Lock)
    threads: list[threading.Thread] = field(default_factory=list)


class SocketcandServer:
    """Serves `buses` (socketcand bus name -> python-can `virtual` channel of this
    process) on 127.0.0.1; `start()` returns the port. `stop()` is safe twice."""

    def __init__(self, buses: Mapping[str, str], port: int = 0) -> None:
        for name in buses:
            if not name or len(name) > MAX_BUS_NAME or any(c in name for c in " <>"):
                raise ValueError(f"socketcand bus name {name!r}: 1-{MAX_BUS_NAME} "
                                 "characters, no spaces or angle brackets")
        self.buses = dict(buses)
        self.host = LOOPBACK_HOST
        self.port = int(port)
        self._listener: socket.socket | None = None
        self._stop = threading.Event()
        self._clients: list[_Client] = []
        self._clients_lock = threading.Lock()
        self._bus_handles: dict[str, can.BusABC] = {}
        self._threads: list[threading.Thread] = []
        #: malformed commands ignored, per peer (the daemon logs them and goes on)
        self.malformed = 0

    # -- life cycle ------------------------------------------------------------------------
    def start(self) -> int:
        if self._listener is not None:
            return self.port
        self._stop.clear()
        for name, channel in self.buses.items():
            self._bus_handles[name] = can.Bus(interface="virtual", channel=channel)
        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            listener.bind((self.host, self.port))
            listener.listen(16)
        except OSError:
            listener.close()
            self._close_buses()
            raise
        listener.settimeout(0.2)
        self._listener = listener
        self.port = int(listener.getsockname()[1])
        self._spawn(self._accept_loop, "socketcand-accept")
        for name in self.buses:
            self._spawn(self._pump, f"socketcand-bus-{name}", name)
        return self.port

    def stop(self) -> None:
        """Close every connection cleanly (FIN, not RST: python-can's client spins on a
        connection reset under it) and leave the buses."""
        if self._listener is None:
            return
        self._stop.set()
        with self._clients_lock:
            clients = list(self._clients)
        for c in clients:
            self._close_client(c)
        for t in self._threads:
            t.join(timeout=2.0)
        self._threads.clear()
        with contextlib.suppress(OSError):
            self._listener.close()
        self._listener = None
        self._close_buses()

    def __enter__(self) -> SocketcandServer:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _close_buses(self) -> None:
        for bus in self._bus_handles.values():
            with contextlib.suppress(Exception):
                bus.shutdown()
        self._bus_handles.clear()

    def _spawn(self, target: Callable[..., None], name: str, *args: str) -> threading.Thread:
        t = threading.Thread(target=target, args=args, name=name, daemon=True)
        self._threads.append(t)
        t.start()
        return t

    @property
    def clients(self) -> int:
        with self._clients_lock:
            return len(self._clients)

    @property
    def raw_clients(self) -> int:
        """Clients in raw mode (frames go to them)."""
        with self._clients_lock:
            return sum(c.raw for c in self._clients)

    # -- the bus side ----------------------------------------------------------------------
    def _pump(self, name: str) -> None:
        """Frames from the twins (this process's virtual bus) to the bus's raw clients."""
        bus = self._bus_handles[name]
        while not self._stop.is_set():
            try:
                msg = bus.recv(0.1)
            except Exception:  # noqa: BLE001 - the bus closed under us at stop
                if self._stop.is_set():
                    return
                raise
            if msg is not None:
                self._broadcast(name, frame_line(msg), sender=None)
            else:
                self._release_due(name)

    def _broadcast(self, bus: str, line: str, sender: _Client | None) -> None:
        with self._clients_lock:
            targets = [c for c in self._clients if c.bus == bus and c.raw and c is not sender]
        for c in targets:
            self._deliver(c, line)

    def _deliver(self, c: _Client, line: str) -> None:
        with c.lock:
            if not c.raw:
                return
            if not c.released:
                if time.monotonic() - c.raw_since < HANDSHAKE_HOLD_S:
                    c.held.append(line)
                    return
                self._release_locked(c)
            self._enqueue(c, line)

    def _release_due(self, bus: str) -> None:
        with self._clients_lock:
            waiting = [c for c in self._clients if c.bus == bus and not c.released]
        now = time.monotonic()
        for c in waiting:
            with c.lock:
                if not c.released and now - c.raw_since >= HANDSHAKE_HOLD_S:
                    self._release_locked(c)

    def _release_locked(self, c: _Client) -> None:
        c.released = True
        while c.held:
            self._enqueue(c, c.held.popleft())

    def _enqueue(self, c: _Client, line: str | None) -> None:
        while True:
            try:
                c.out.put_nowait(line)
                return
            except queue.Full:
                with contextlib.suppress(queue.Empty):
                    c.out.get_nowait()
                    c.dropped += 1

    # -- the TCP side ----------------------------------------------------------------------
    def _accept_loop(self) -> None:
        assert self._listener is not None
        listener = self._listener
        while not self._stop.is_set():
            try:
                sock, peer = listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            sock.settimeout(None)
            c = _Client(sock, f"{peer[0]}:{peer[1]}")
            with self._clients_lock:
                self._clients.append(c)
            c.threads.append(self._client_thread(self._writer, c, "w"))
            self._enqueue(c, HI)
            c.threads.append(self._client_thread(self._reader, c, "r"))

    def _client_thread(self, target: Callable[[_Client], None], c: _Client, kind: str
                       ) -> threading.Thread:
        t = threading.Thread(target=target, args=(c,), name=f"socketcand-{kind}-{c.peer}",
                             daemon=True)
        t.start()
        return t

    def _writer(self, c: _Client) -> None:
        while True:
            try:
                line = c.out.get(timeout=0.1)
            except queue.Empty:
                if self._stop.is_set():
                    return
                continue
            if line is None:
                return
            try:
                c.sock.sendall(line.encode("ascii"))
            except OSError:
                return

    def _reader(self, c: _Client) -> None:
        buf = ""
        try:
            while not self._stop.is_set():
                try:
                    chunk = c.sock.recv(4096)
                except OSError:
                    break
                if not chunk:
                    break
                buf += chunk.decode("ascii", errors="replace")
                end = buf.rfind(">")
                if end < 0:
                    if len(buf) > 4096:   # no command this long: not a socketcand client
                        break
                    continue
                for command in _COMMAND.findall(buf[:end + 1]):
                    if not self._command(c, command):
                        return
                buf = buf[end + 1:]
        finally:
            self._close_client(c)

    def _command(self, c: _Client, command: str) -> bool:
        """One command in the client's mode; False when the connection is to end."""
        norm = " ".join(command[1:-1].split())
        word = norm.split(" ", 1)[0] if norm else ""
        with c.lock:
            if c.raw and not c.released:    # it sent a command: it has read our ok
                self._release_locked(c)
        if c.bus is None:                              # mode NO_BUS
            if word == "open":
                name = norm[5:].strip()
                if name in self.buses:
                    c.bus = name
                    self._enqueue(c, OK)
                    return True
                self._enqueue(c, ERROR_OPEN)
                return False
            self._enqueue(c, ERROR_UNKNOWN)
            return True
        if word == "echo":
            self._enqueue(c, "< echo >")
        elif word == "rawmode":
            with c.lock:
                self._enqueue(c, OK)
                c.raw, c.released, c.raw_since = True, False, time.monotonic()
        elif word == "bcmmode":
            with c.lock:
                c.raw, c.released = False, True
                c.held.clear()
                self._enqueue(c, OK)
        elif word in ("send", "sendrtr"):
            msg = parse_send(command)
            if msg is None:
                self.malformed += 1
                log.warning("socketcand %s: malformed %r ignored", c.peer, command)
                return True
            msg.timestamp = time.time()
            handle = self._bus_handles.get(c.bus)
            if handle is not None:
                handle.send(msg)
            self._broadcast(c.bus, frame_line(msg), sender=c)
        else:
            self._enqueue(c, ERROR_UNKNOWN)
        return True

    def _close_client(self, c: _Client) -> None:
        with self._clients_lock:
            if c not in self._clients:
                return
            self._clients.remove(c)
        with c.lock:
            c.raw = False
            c.held.clear()
        self._enqueue(c, None)              # the writer sends what is queued, then ends
        me = threading.current_thread()
        writer, reader = c.threads[0], c.threads[-1]
        if writer is not me:
            writer.join(timeout=1.0)
        with contextlib.suppress(OSError):
            c.sock.shutdown(socket.SHUT_WR)     # FIN after the last line
        with contextlib.suppress(OSError):
            c.sock.shutdown(socket.SHUT_RD)     # wakes our reader's recv
        if reader is not me:
            reader.join(timeout=1.0)
        with contextlib.suppress(OSError):
            c.sock.close()
