"""The byte seam under every SCPI driver: a real VISA session, or a literal transcript.

Why a seam: a driver must be checked against what the instrument's MANUAL says it
exchanges, not only against our own twin (which could share the driver's mistake). The
model is PyMeasure's `expected_protocol` (pymeasure.test): a list of (sent, reply) pairs
written by hand from the manual; the driver runs against that list with no server, and
any message it sends that the list does not expect, in that order, fails the test.

    with expected_protocol(lambda t: Counter(..., transport=t), [
            ("*IDN?", "Keysight Technologies,53230A,MY1,1"),
            ("SYST:TIM?", "+1.00000000E+000"),          # Programmer's Ref. p. 459
            ...]) as counter:
        counter.identify()

A pair's reply is the instrument's answer as text (the terminator is added), or None
for a command that has none. The same pairs are replayed against the twins over their
real channel (tests/transcripts.py), so twin and driver meet the same manual text.
"""

from __future__ import annotations

import contextlib
import re
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, TypeVar, cast

if TYPE_CHECKING:  # pyvisa is imported where a link is opened, not at import
    from pyvisa.resources import MessageBasedResource


class TransportTimeout(TimeoutError):
    """No (complete) reply within the time allowed."""


class Transport(Protocol):
    """What a message-based driver needs from the link to its instrument."""

    def write(self, data: bytes) -> None: ...

    def read(self, timeout_s: float) -> bytes:
        """One reply message, terminator included; TransportTimeout when none came."""
        ...

    def clear(self) -> None:
        """Device clear where the interface has one (GPIB, USBTMC, VXI-11), else nothing."""
        ...

    def close(self) -> None: ...


class VisaTransport:
    """A pyvisa session (raw socket, USBTMC, GPIB ...): the transport of a real bench."""

    def __init__(self, resource: str, *, visa_library: str = "@py",
                 read_termination: str = "\n", write_termination: str = "\n",
                 timeout_s: float = 2.0, open_timeout_s: float = 5.0) -> None:
        import pyvisa

        self.resource = resource
        self._rm = pyvisa.ResourceManager(visa_library)
        try:
            # a message-based resource (TCPIP SOCKET/INSTR, ASRL, USB): raw reads and writes
            self._inst = cast("MessageBasedResource", self._rm.open_resource(
                resource, read_termination=read_termination,
                write_termination=write_termination, timeout=_ms(timeout_s),
                open_timeout=_ms(open_timeout_s)))
        except BaseException:
            with contextlib.suppress(Exception):
                self._rm.close()
            raise
        self._default_timeout_ms = _ms(timeout_s)
        if resource.upper().endswith("::SOCKET"):
            _socket_options(self._inst)

    def write(self, data: bytes) -> None:
        self._inst.write_raw(data)

    def read(self, timeout_s: float) -> bytes:
        import pyvisa

        self._inst.timeout = _ms(timeout_s)
        try:
            return bytes(self._inst.read_raw())
        except pyvisa.errors.VisaIOError as e:
            if e.error_code == pyvisa.constants.StatusCode.error_timeout:
                raise TransportTimeout(str(e)) from e
            raise
        finally:
            with contextlib.suppress(Exception):
                self._inst.timeout = self._default_timeout_ms

    def clear(self) -> None:
        """Not on a raw socket: it has no device clear, and pyvisa-py's `clear()` there
        spins forever once the peer has closed."""
        if self.resource.upper().endswith("::SOCKET"):
            return
        with contextlib.suppress(Exception):
            self._inst.clear()

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self._inst.close()
        with contextlib.suppress(Exception):
            self._rm.close()


def _ms(seconds: float) -> int:
    return max(1, int(round(seconds * 1000.0)))


def _socket_options(inst: MessageBasedResource) -> None:
    """TCP_NODELAY and keepalive on a raw SCPI socket.

    Without NODELAY a command and its SYST:ERR? wait for the instrument's delayed ACK
    (40 ms or more each, Nagle); NI-VISA sets it by default, pyvisa-py 0.8 does not, and
    its VI_ATTR_TCPIP_NODELAY setter is mis-wired (raises UnknownAttribute; see
    nominal-io/instro#156), so we set it on pyvisa-py's socket when we find one.
    Keepalive lets a long wait notice a dead link.
    """
    import socket

    import pyvisa

    with contextlib.suppress(Exception):
        inst.set_visa_attribute(pyvisa.constants.ResourceAttribute.tcpip_keepalive, True)
    sessions = getattr(inst.visalib, "sessions", None)  # pyvisa-py only
    sock = getattr(sessions.get(inst.session), "interface", None) if sessions else None
    if isinstance(sock, socket.socket):
        with contextlib.suppress(OSError):
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        return
    with contextlib.suppress(Exception):
        inst.set_visa_attribute(pyvisa.constants.ResourceAttribute.tcpip_nodelay, True)


# -- transcripts ----------------------------------------------------------------------

@dataclass(frozen=True)
class Like:
    """A reply in a transcript that the twin must match as a pattern, not literally.

    The driver side gets `text` (the manual's literal example); a twin replaying the
    transcript must answer something `pattern` matches in full (its values come from the
    stand's truth, so only their form can be fixed: a prescaler, count values, NR3).
    """

    text: str
    pattern: str

    def matches(self, reply: str) -> bool:
        return re.fullmatch(self.pattern, reply) is not None


Reply = str | Like | None
Exchange = tuple[str, Reply]


class TranscriptMismatch(AssertionError):
    """The driver sent something the manual's transcript does not have at that point."""


class TranscriptTransport:
    """Plays the instrument's side of a hand-written transcript (no server).

    Each `write` must be the next expected message (terminator stripped, compared
    exactly); its reply, if any, is queued for the next `read`. A `read` with nothing
    queued is the instrument saying nothing: TransportTimeout, as on a real link.
    """

    def __init__(self, exchanges: Sequence[Exchange], *, termination: str = "\n") -> None:
        self.exchanges = list(exchanges)
        self.termination = termination
        self.position = 0
        self._replies: deque[bytes] = deque()
        self.closed = False

    def write(self, data: bytes) -> None:
        text = data.decode("ascii").removesuffix(self.termination)
        if self.position >= len(self.exchanges):
            raise TranscriptMismatch(f"sent {text!r} after the transcript's last exchange "
                                     f"({len(self.exchanges)} exchanges)")
        sent, reply = self.exchanges[self.position]
        if text != sent:
            raise TranscriptMismatch(f"exchange {self.position + 1}: sent {text!r}, the "
                                     f"transcript expects {sent!r}")
        self.position += 1
        if reply is not None:
            shown = reply.text if isinstance(reply, Like) else reply
            self._replies.append((shown + self.termination).encode("ascii"))

    def read(self, timeout_s: float) -> bytes:
        if not self._replies:
            raise TransportTimeout(f"no reply queued after exchange {self.position}")
        return self._replies.popleft()

    def clear(self) -> None:
        self._replies.clear()

    def close(self) -> None:
        self.closed = True

    def assert_done(self) -> None:
        left = self.exchanges[self.position:]
        if left:
            raise TranscriptMismatch(f"{len(left)} exchange(s) of the transcript never "
                                     f"happened, the first: {left[0][0]!r}")
        if self._replies:
            raise TranscriptMismatch(f"{len(self._replies)} reply(ies) never read")


T = TypeVar("T")


@contextlib.contextmanager
def expected_protocol(make: Callable[[TranscriptTransport], T],
                      exchanges: Sequence[Exchange]) -> Iterator[T]:
    """Build a driver on a transcript; on leaving, every exchange must have happened."""
    transport = TranscriptTransport(exchanges)
    inst = make(transport)
    yield inst
    transport.assert_done()
