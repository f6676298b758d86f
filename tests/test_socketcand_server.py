"""The twins' socketcand server against the protocol's own words and its clients.

Sources: linux-can/socketcand doc/protocol.md (modes NO_BUS, BCM, RAW; `< send >`,
`< frame >`, `< echo >`), and where the document and the daemon differ, the daemon's
src/state_nobus.c and src/state_raw.c (frame data as `%02X` run together, the empty data
token of a zero-length frame, `< error could not open bus >` then the connection ends).
The clients: a raw TCP socket speaking those lines (a script nobody here wrote would do
the same), and python-can's own `socketcand` interface.
"""

from __future__ import annotations

import re
import socket
import time
import uuid
from collections.abc import Iterator

import can
import msgspec
import pytest

from bench.core.canbus import AxisBus, BusNode, bus_name
from bench.core.canbus import bus_problems as _bus_problems
from sims.socketcand_server import HANDSHAKE_HOLD_S, SocketcandServer, frame_line, parse_send

pytestmark = pytest.mark.timeout(60)

FRAME = re.compile(r"< frame ([0-9A-F]{3}|[0-9A-F]{8}) (\d+)\.(\d{6}) ([0-9A-F]*) >")


@pytest.fixture
def served() -> Iterator[tuple[SocketcandServer, can.BusABC]]:
    """A server for bus `bench` and a twin's end of it (this process's virtual bus)."""
    channel = f"sc-{uuid.uuid4().hex[:10]}"
    twin = can.Bus(interface="virtual", channel=channel)
    server = SocketcandServer({"bench": channel})
    server.start()
    try:
        yield server, twin
    finally:
        server.stop()
        twin.shutdown()


class LineClient:
    """A raw TCP client that reads the server's `< ... >` lines one at a time."""

    def __init__(self, port: int) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=5.0)
        self.buf = ""

    def line(self, timeout_s: float = 5.0) -> str | None:
        deadline = time.monotonic() + timeout_s
        while ">" not in self.buf:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            self.sock.settimeout(left)
            try:
                chunk = self.sock.recv(4096)
            except TimeoutError:
                return None
            if not chunk:
                return "" if not self.buf else None
            self.buf += chunk.decode("ascii")
        start, end = self.buf.index("<"), self.buf.index(">")
        out, self.buf = self.buf[start:end + 1], self.buf[end + 1:]
        return out

    def send(self, text: str) -> None:
        self.sock.sendall(text.encode("ascii"))

    def open_bus(self, name: str = "bench") -> None:
        """The greeting, then `< open NAME >` answered `< ok >` (mode BCM)."""
        assert self.line() == "< hi >"
        self.send(f"< open {name} >")
        assert self.line() == "< ok >"

    def close(self) -> None:
        self.sock.close()


def test_handshake_words_and_an_unknown_bus(served: tuple[SocketcandServer, can.BusABC]) -> None:
    server, _ = served
    c = LineClient(server.port)
    try:
        assert c.line() == "< hi >"
        c.send("< open can9 >")
        assert c.line() == "< error could not open bus >"
        assert c.line() == ""                    # and the server ends the connection
    finally:
        c.close()
    c = LineClient(server.port)
    try:
        assert c.line() == "< hi >"
        c.send("< rawmode >")                   # no bus yet: mode NO_BUS knows only open
        assert c.line() == "< error unknown command >"
        c.send("< open bench >")
        assert c.line() == "< ok >"
        c.send("< echo >")
        assert c.line() == "< echo >"
        c.send("< subscribe 0 0 123 >")          # BCM jobs: not served, said at once
        assert c.line() == "< error unknown command >"
    finally:
        c.close()


def test_raw_mode_frames_in_the_daemons_format(
        served: tuple[SocketcandServer, can.BusABC]) -> None:
    server, twin = served
    c = LineClient(server.port)
    try:
        c.open_bus()
        c.send("< rawmode >")
        assert c.line() == "< ok >"
        c.send("< echo >")                       # a command: it has read the ok
        assert c.line() == "< echo >"
        twin.send(can.Message(arbitration_id=0x080, data=b"", is_extended_id=False))
        twin.send(can.Message(arbitration_id=0x182, data=bytes([0x27, 0x06, 0xAB]),
                              is_extended_id=False))
        twin.send(can.Message(arbitration_id=0x1AAAAAAA, data=b"\x01\xf1",
                              is_extended_id=True))
        sync, tpdo, ext = c.line(), c.line(), c.line()
        assert sync is not None and re.fullmatch(r"< frame 080 \d+\.\d{6}  >", sync), sync
        assert tpdo is not None and (m := FRAME.fullmatch(tpdo)) and m[1] == "182" \
            and m[4] == "2706AB", tpdo
        assert ext is not None and (m := FRAME.fullmatch(ext)) and m[1] == "1AAAAAAA" \
            and m[4] == "01F1", ext
        # `< send >`: the document's own examples, and python-can's lower-case unpadded bytes
        c.send("< send 123 0 >< send 1AAAAAAA 2 1 F1 >< send 602 8 40 0 10 0 0 0 0 0 >")
        got = [twin.recv(2.0) for _ in range(3)]
        assert [(m.arbitration_id, m.is_extended_id, bytes(m.data)) for m in got if m] == [
            (0x123, False, b""), (0x1AAAAAAA, True, b"\x01\xf1"),
            (0x602, False, bytes([0x40, 0, 0x10, 0, 0, 0, 0, 0]))]
        # malformed: ignored as the daemon does (count mismatch, 9 bytes, bad id)
        c.send("< send 123 2 11 >< send 123 9 1 2 3 4 5 6 7 8 9 >< send XYZ 0 >")
        c.send("< echo >")
        assert c.line() == "< echo >"
        assert twin.recv(0.2) is None and server.malformed == 3
        c.send("< bcmmode >")                    # back to BCM: no frames follow
        assert c.line() == "< ok >"
        twin.send(can.Message(arbitration_id=0x702, data=b"\x05", is_extended_id=False))
        c.send("< echo >")
        assert c.line() == "< echo >"
    finally:
        c.close()


def test_rawmode_reply_travels_alone_then_held_frames_follow(
        served: tuple[SocketcandServer, can.BusABC]) -> None:
    """python-can reads the rawmode `< ok >` with one recv and compares it exactly: frames
    on a busy bus must not share its segment. They are held (not lost) until the client
    speaks or HANDSHAKE_HOLD_S passes."""
    server, twin = served
    c = LineClient(server.port)
    try:
        c.open_bus()
        c.send("< rawmode >")
        deadline = time.monotonic() + 5.0        # the server has switched it to raw (a
        while server.raw_clients < 1 and time.monotonic() < deadline:  # frame before
            time.sleep(0.001)                    # that is not for it, as on a real bus)
        assert server.raw_clients == 1
        for i in range(20):                      # the bus is busy right after the reply
            twin.send(can.Message(arbitration_id=0x700 + 2, data=bytes([i])))
        time.sleep(0.05)
        c.sock.settimeout(2.0)
        assert c.sock.recv(256) == b"< ok >"     # alone, as python-can's _expect_msg reads
        t0 = time.monotonic()
        lines = [c.line(3.0) for _ in range(20)]
        assert time.monotonic() - t0 <= HANDSHAKE_HOLD_S + 1.0
        assert [FRAME.fullmatch(x or "")[4] for x in lines] == [f"{i:02X}" for i in range(20)]
    finally:
        c.close()


def test_python_can_clients_see_every_frame_but_their_own(
        served: tuple[SocketcandServer, can.BusABC]) -> None:
    server, twin = served
    kw = {"interface": "socketcand", "host": "127.0.0.1", "port": server.port,
          "channel": "bench"}
    with can.Bus(**kw) as a, can.Bus(**kw) as b:
        a.send(can.Message(arbitration_id=0x000, data=b"\x01\x02", is_extended_id=False))
        from_a = twin.recv(2.0)
        assert from_a is not None and bytes(from_a.data) == b"\x01\x02"
        heard = b.recv(2.0)
        assert heard is not None and heard.arbitration_id == 0 and bytes(heard.data) == b"\x01\x02"
        assert a.recv(0.3) is None               # a real controller does not echo its own
        twin.send(can.Message(arbitration_id=0x080, data=b"", is_extended_id=False))
        for bus in (a, b):                       # the SYNC: a zero-length frame parses
            m = bus.recv(2.0)
            assert m is not None and m.arbitration_id == 0x80 and m.dlc == 0


def test_stop_ends_connections_cleanly_and_is_safe_twice(
        served: tuple[SocketcandServer, can.BusABC]) -> None:
    server, _ = served
    c = LineClient(server.port)
    assert c.line() == "< hi >"
    t0 = time.monotonic()
    server.stop()
    server.stop()
    assert time.monotonic() - t0 < 3.0
    assert c.line() == ""                        # an orderly end of stream, not a reset
    c.close()
    assert server.clients == 0


def test_frame_and_send_lines_round_trip() -> None:
    for msg in (can.Message(arbitration_id=0x7FF, data=bytes(range(8)), is_extended_id=False),
                can.Message(arbitration_id=0x1FFFFFFF, data=b"", is_extended_id=True)):
        line = frame_line(msg)
        m = FRAME.fullmatch(line)
        assert m is not None, line
        ident, data = m[1], bytes.fromhex(m[4])
        send = f"< send {ident} {len(data)} {' '.join(f'{x:x}' for x in data)} >"
        back = parse_send(send)
        assert back is not None and back.arbitration_id == msg.arbitration_id
        assert back.is_extended_id == msg.is_extended_id and bytes(back.data) == bytes(msg.data)
    assert parse_send("< send 800 0 >") is None    # 11-bit id out of range
    rtr = parse_send("< sendrtr 123 4 >")
    assert rtr is not None and rtr.is_remote_frame and rtr.dlc == 4


def test_a_stands_socketcand_bus_is_named_by_its_server() -> None:
    """Two servers' `can0` are two buses (node ids may repeat across them); one server's
    `can0` shared by two axes is one bus (they may not); host and port are required."""
    a = {"interface": "socketcand", "channel": "can0", "host": "127.0.0.1", "port": 29536}
    b = dict(a, port=29537)
    def bus_problems(axes: dict[str, dict]) -> list[tuple[tuple[str, ...], str]]:
        return _bus_problems(msgspec.convert(axes, dict[str, AxisBus]))

    def node(d: dict) -> BusNode:
        return BusNode(node_id=2, **d)

    assert bus_name(node(a)) != bus_name(node(b))
    assert bus_name(node(a)) == "socketcand:can0@127.0.0.1:29536"
    assert bus_problems({"x": {"drive": dict(a, node_id=2)},
                         "y": {"drive": dict(b, node_id=2)}}) == []
    clash = bus_problems({"x": {"drive": dict(a, node_id=2)},
                          "y": {"drive": dict(a, node_id=2)}})
    assert [p[0] for p in clash] == [("y", "drive", "node_id")]
    missing = bus_problems({"x": {"drive": {"interface": "socketcand", "channel": "can0",
                                            "node_id": 2}}})
    assert [m for _, m in missing] == [
        "interface socketcand needs drive.host (the server's address, e.g. 127.0.0.1)",
        "interface socketcand needs drive.port (the server's TCP port)"]
