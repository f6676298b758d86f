"""A SCPI instrument on a TCP socket: the base every SCPI twin (counter, AWG, DMM) builds on.

What a real LAN instrument's raw SCPI socket (port 5025) does, as far as a driver can
tell: it listens on 127.0.0.1 (an ephemeral port unless told), serves one client at a
time (the next waits in the listen queue until the first disconnects), reads newline-
terminated program messages, runs each `;`-separated unit, answers queries on one line
(several answers joined by `;`), and keeps an IEEE 488.2 / SCPI error queue (20 entries,
-350 on overflow) with the standard event status register (ESR) bits that go with it.

A subclass routes its words, which it imports from drivers/ (one place for a protocol's
constants), to handlers:

    class Dmm(ScpiServer):
        fault_names = ScpiServer.fault_names | {"overload"}
        def __init__(self) -> None:
            super().__init__(idn="Sim,DMM,0,1")
            self.route(VOLT_RANGE, on_set=self._set_range, on_query=lambda a: nr3(self.range))
            self.route(READ, on_query=self._read, data=True)

(or `route_words(words, {"range": (on_set, on_query), ...})` for a words dataclass.)
A handler receives the header's numeric suffixes and the parameters as strings, by
placeholder name, and returns the reply text (queries) or None; it raises `ExecError`
for the error queue (-222 "Data out of range" ...). The parameter parsers at the end
(`number_param`, `ranged_param`, `count_param`, `bool_param`, `enum_param`,
`suffix_item`) raise the codes a real instrument would. A handler that must wait (a
measurement) calls `self.wait(ready)`, which keeps reading the socket meanwhile: the
client may disconnect, or send a line for which `is_interrupt()` is true (ABORt, our
stand-in for a device clear, which a raw socket lacks), and the wait then ends with no
reply. Overlapped operations (INIT) report through `pending()`, which `*OPC?`, `*OPC`
and `*WAI` honour.

Header compounding (SCPI-99 vol. 1, 6.2.4): after `;` a header without a leading `:`
continues from the previous header's path (`TRIG:SOUR IMM; COUN MAX` is TRIG:COUN); a
leading `:` starts from the root; common commands (`*...`) leave the path alone. A
header the path makes unknown is -113, as on the instrument.

A route with `raw=True` gets its whole parameter text as `args["raw"]`, for parameter
lists a template cannot say (`MEAS:PER? DEF,DEF,(@1)`, `FORM ASC,15`, `R? 100`).

Faults, injected from the test's thread with `inject(name, count=1)`, act on the next
data query (a route with `data=True`): 'garbage' replaces its reply with bytes that are
not a SCPI reply; 'drop' closes the connection instead of answering. Subclasses add
their own (the counter twin: 'no-trigger').
"""

from __future__ import annotations

import collections
import contextlib
import select
import socket
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import ClassVar, TypeVar

from drivers.scpi import (
    ABORT,
    CLS,
    ESR_OPC,
    ESR_Q,
    IDN,
    OPC,
    OPC_Q,
    RST,
    SYST_ERR,
    WAI,
    Command,
    ErrorEntry,
    ParameterError,
    short_form,
)

Handler = Callable[[Mapping[str, str]], "str | bytes | None"]
#: a word's handlers in a `route_words` table: (on_set, on_query) or (on_set, on_query, data)
WordHandlers = tuple[Handler | None, Handler | None] | tuple[Handler | None, Handler | None, bool]
T = TypeVar("T")

#: what a 'garbage' fault sends instead of the reply (not ASCII, not numbers)
GARBAGE = b"\xff\xfe#?\x00garbage\x15\n"

_POLL_S = 0.02
#: clock seconds a waiting handler lets pass between looks on a stepped clock
_STEPPED_POLL_S = 0.01


class ExecError(Exception):
    """Raised by a handler: queue `code, "message"` (e.g. -222, "Data out of range")."""

    def __init__(self, code: int, message: str) -> None:
        super().__init__(f"{code},{message}")
        self.code = code
        self.message = message


class _ClientGone(Exception):
    """The client disconnected, a 'drop' fault fired, or the server is stopping."""


class _Interrupted(Exception):
    """An interrupting line (ABORt) arrived while a handler waited: no reply."""


@dataclass(frozen=True)
class Route:
    command: Command
    on_set: Handler | None
    on_query: Handler | None
    data: bool
    raw: bool = False


def esr_bit_for(code: int) -> int:
    """IEEE 488.2 ESR bit for a SCPI error code's class (SCPI-99 vol. 2, §21.8)."""
    if -199 <= code <= -100:
        return 0x20  # command error
    if -299 <= code <= -200:
        return 0x10  # execution error
    if -399 <= code <= -300 or code > 0:
        return 0x08  # device-specific error
    if -499 <= code <= -400:
        return 0x04  # query error
    return 0


class ScpiServer:
    """A SCPI instrument on 127.0.0.1; see the module docstring."""

    fault_names: ClassVar[frozenset[str]] = frozenset({"garbage", "drop"})
    max_errors: ClassVar[int] = 20

    def __init__(self, idn: str = "Simulated,SCPI instrument,0,0", host: str = "127.0.0.1",
                 port: int = 0) -> None:
        self.idn = idn
        self.host = host
        self.port = port
        self.routes: list[Route] = []
        self.errors: collections.deque[ErrorEntry] = collections.deque()
        self.esr = 0
        self.received: collections.deque[str] = collections.deque(maxlen=2000)
        self.sessions = 0
        self._opc_pending = False
        self._faults: dict[str, int] = {}
        self._lock = threading.RLock()
        self._listener: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._conn: socket.socket | None = None
        self._inbox: collections.deque[str] = collections.deque()
        self._buffer = bytearray()
        self.route(IDN, on_query=lambda a: self.idn)
        self.route(RST, on_set=lambda a: self.reset())
        self.route(CLS, on_set=lambda a: self.clear_status())
        self.route(OPC_Q, on_query=self._opc_query)
        self.route(OPC, on_set=self._opc)
        self.route(WAI, on_set=lambda a: self.wait(lambda: not self.pending()))
        self.route(ESR_Q, on_query=self._esr_query)
        self.route(SYST_ERR, on_query=lambda a: self.error_text(self.pop_error()))

    # -- lifecycle --------------------------------------------------------------------------
    def start(self) -> str:
        """Listen and serve in a thread; returns the VISA resource string."""
        if self._thread is not None:
            return self.resource
        ls = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        ls.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        ls.bind((self.host, self.port))
        ls.listen(4)
        self.port = ls.getsockname()[1]
        self._listener = ls
        self._stop.clear()
        self._thread = threading.Thread(target=self._serve, name=f"{type(self).__name__}:"
                                        f"{self.port}", daemon=True)
        self._thread.start()
        return self.resource

    def stop(self) -> None:
        self._stop.set()
        t, self._thread = self._thread, None
        if t is not None:
            t.join(timeout=5.0)
        if self._listener is not None:
            with contextlib.suppress(OSError):
                self._listener.close()
            self._listener = None

    @property
    def resource(self) -> str:
        return f"TCPIP0::{self.host}::{self.port}::SOCKET"

    def __enter__(self) -> ScpiServer:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- routes, errors, faults -----------------------------------------------------------
    def route(self, command: Command, on_set: Handler | None = None,
              on_query: Handler | None = None, data: bool = False, raw: bool = False,
              first: bool = False) -> None:
        """Serve a word: `on_set` for the command, `on_query` for its query form;
        `raw`: the parameter text unparsed (args["raw"]); `first`: ahead of the routes
        already there (a model's own form of a word)."""
        if command.is_query and on_set is not None:
            raise ValueError(f"{command.header!r} is a query; give on_query only")
        r = Route(command, on_set, on_query, data, raw)
        if first:
            self.routes.insert(0, r)
        else:
            self.routes.append(r)

    def route_words(self, words: object, table: Mapping[str, WordHandlers]) -> None:
        """Serve a words dataclass by role: `table[role]` is (on_set, on_query[, data]).

        A role the model has no word for (None) is skipped; a query-only word gets its
        `on_query` alone.
        """
        for role, (on_set, on_query, *data) in table.items():
            cmd: Command | None = getattr(words, role)
            if cmd is None:
                continue
            self.route(cmd, on_set=None if cmd.is_query else on_set, on_query=on_query,
                       data=bool(data and data[0]))

    def push_error(self, code: int, message: str) -> None:
        with self._lock:
            self.esr |= esr_bit_for(code)
            if len(self.errors) >= self.max_errors:
                self.errors[-1] = ErrorEntry(-350, "Queue overflow")
                return
            self.errors.append(ErrorEntry(code, message))

    def pop_error(self) -> ErrorEntry:
        with self._lock:
            return self.errors.popleft() if self.errors else ErrorEntry(0, "No error")

    #: how an error entry's code is printed: "{:d}" (`0,"No error"`, SCPI-99) or
    #: "{:+d}" (`+0,"No error"`, as Keysight's manuals print it)
    error_code_format: str = "{:d}"   # a twin may set its own (the 53230A: "{:+d}")

    def error_text(self, entry: ErrorEntry) -> str:
        return f'{self.error_code_format.format(entry.code)},"{entry.message}"'

    def clear_status(self) -> None:
        """*CLS: the error queue, the ESR and a pending *OPC."""
        with self._lock:
            self.errors.clear()
            self.esr = 0
            self._opc_pending = False

    def inject(self, fault: str, count: int = 1) -> None:
        """Arm a fault for the next `count` occasions (see the module docstring)."""
        if fault not in self.fault_names:
            raise ValueError(f"unknown fault {fault!r}; known: {', '.join(sorted(self.fault_names))}")
        with self._lock:
            self._faults[fault] = self._faults.get(fault, 0) + count

    def take_fault(self, fault: str) -> bool:
        """True (once per injected count) if `fault` is armed."""
        with self._lock:
            n = self._faults.get(fault, 0)
            if n <= 0:
                return False
            self._faults[fault] = n - 1
            return True

    # -- hooks for subclasses ---------------------------------------------------------------
    def reset(self) -> None:
        """*RST: back to the factory state (subclasses reset their settings)."""

    def pending(self) -> bool:
        """An overlapped operation (a measurement after INIT) is still running."""
        return False

    def session_ended(self) -> None:
        """The client went away (subclasses abandon what it had started)."""

    def is_interrupt(self, line: str) -> bool:
        """A line that ends a waiting query with no reply (default: ABORt)."""
        header = line.strip().split(None, 1)[0] if line.strip() else ""
        return ABORT.match(header) is not None

    # -- waiting ----------------------------------------------------------------------------
    def wait(self, ready: Callable[[], bool], poll_s: float = _POLL_S) -> None:
        """Block a handler until `ready()`, reading the client meanwhile.

        Raises (internally) when the client leaves or an interrupting line arrives. On a
        stepped clock (sims/clock.py) the client is blocked on this reply, so the wait
        lets the instrument's clock time pass itself, `_STEPPED_POLL_S` at a time.
        """
        clock = getattr(self, "clock", None)
        stepped = bool(getattr(clock, "stepped", False))
        while not ready():
            if stepped and clock is not None and clock.running:
                clock.sleep(_STEPPED_POLL_S)
                self._pump(0.0)
            else:
                self._pump(poll_s)
            if any(self.is_interrupt(line) for line in self._inbox):
                raise _Interrupted

    def _pump(self, timeout_s: float) -> None:
        """Move what the client sent into the inbox (lines), or raise if it left."""
        if self._stop.is_set() or self._conn is None:
            raise _ClientGone
        r, _, _ = select.select([self._conn], [], [], timeout_s)
        if not r:
            return
        try:
            data = self._conn.recv(65536)
        except OSError as e:
            raise _ClientGone from e
        if not data:
            raise _ClientGone
        self._buffer.extend(data)
        while b"\n" in self._buffer:
            i = self._buffer.index(b"\n")
            line = bytes(self._buffer[:i]).decode("ascii", "replace").rstrip("\r")
            del self._buffer[:i + 1]
            self._inbox.append(line)

    # -- serving ----------------------------------------------------------------------------
    def _serve(self) -> None:
        assert self._listener is not None
        while not self._stop.is_set():
            r, _, _ = select.select([self._listener], [], [], 0.05)
            if not r:
                continue
            try:
                conn, _ = self._listener.accept()
            except OSError:
                continue
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self.sessions += 1
            self._conn, self._buffer, self._inbox = conn, bytearray(), collections.deque()
            try:
                self._session()
            except _ClientGone:
                pass
            finally:
                self._conn = None
                with contextlib.suppress(OSError):
                    conn.close()
                self.session_ended()

    def _session(self) -> None:
        while True:
            while not self._inbox:
                self._pump(0.05)
            line = self._inbox.popleft()
            self.received.append(line)
            reply = self.execute(line)
            if reply is not None and self._conn is not None:
                try:
                    self._conn.sendall(reply)
                except OSError as e:
                    raise _ClientGone from e

    def execute(self, line: str) -> bytes | None:
        """Run one program message; returns the bytes to send (None: nothing)."""
        answers: list[str] = []
        binary: list[bytes] = []
        garbage = False
        path: list[str] = []
        for unit in _split_units(line):
            header, _, params = unit.strip().partition(" ")
            if not header:
                continue
            header, path = _compound(header, path)
            is_query = header.endswith("?")
            found = self._find(header, is_query, params)
            if found is None:
                self.push_error(-113, "Undefined header")
                continue
            route, suffixes = found
            handler = route.on_query if is_query else route.on_set
            if handler is None:
                self.push_error(-113, "Undefined header")
                continue
            try:
                args = {**suffixes, **self._params(route, is_query, params)}
                if route.data and is_query and self.take_fault("drop"):
                    raise _ClientGone
                answer = handler(args)
            except (ParameterError, ExecError) as e:
                self.push_error(e.code, e.message)
                continue
            except _Interrupted:
                return None
            if is_query and answer is not None:
                if isinstance(answer, bytes):
                    binary.append(answer)  # a definite-length block (FORM REAL)
                else:
                    answers.append(answer)
            if is_query and answer is not None and route.data and self.take_fault("garbage"):
                garbage = True
        if garbage:
            return GARBAGE
        if binary:
            return b";".join([*(a.encode("ascii") for a in answers), *binary]) + b"\n"
        if not answers:
            return None
        return (";".join(answers) + "\n").encode("ascii")

    def _find(self, header: str, is_query: bool, params: str = ""
              ) -> tuple[Route, dict[str, str]] | None:
        """The route for a header; where two match (a setting's query form `SAMP:TIM?` and
        a query-only word with a parameter, `SAMP:TIM? MIN`), the one whose parameters
        parse."""
        found = []
        for route in self.routes:
            m = route.command.match(header, query=is_query)
            if m is not None:
                found.append((route, m))
        for route, m in found:
            try:
                self._params(route, is_query, params)
            except ParameterError:
                continue
            return route, m
        return found[0] if found else None

    @staticmethod
    def _params(route: Route, is_query: bool, params: str) -> dict[str, str]:
        if route.raw:
            return {"raw": params.strip()}
        if not is_query or route.command.is_query:
            return route.command.parse_params(params)
        return _no_params(params)

    # -- common commands ------------------------------------------------------------------
    def _opc(self, args: Mapping[str, str]) -> None:
        with self._lock:
            self._opc_pending = True

    def _opc_query(self, args: Mapping[str, str]) -> str:
        self.wait(lambda: not self.pending())
        return "1"

    def _esr_query(self, args: Mapping[str, str]) -> str:
        with self._lock:
            if self._opc_pending and not self.pending():
                self.esr |= ESR_OPC
                self._opc_pending = False
            value, self.esr = self.esr, 0
        return f"+{value}"


def _no_params(params: str) -> dict[str, str]:
    if params.strip():
        raise ParameterError(-108, "Parameter not allowed")
    return {}


def _compound(header: str, path: list[str]) -> tuple[str, list[str]]:
    """SCPI-99 6.2.4: the full header of a unit, and the path the next unit continues
    from (the nodes before this header's last one)."""
    if header.startswith("*"):
        return header, path
    if header.startswith(":"):
        nodes = header[1:].split(":")
    else:
        nodes = [*path, *header.split(":")]
    return ":" + ":".join(nodes), nodes[:-1]


def _split_units(line: str) -> list[str]:
    """Split a program message at `;` outside quoted strings."""
    units, cur, quote = [], [], ""
    for ch in line:
        if quote:
            cur.append(ch)
            if ch == quote:
                quote = ""
        elif ch in "\"'":
            quote = ch
            cur.append(ch)
        elif ch == ";":
            units.append("".join(cur))
            cur = []
        else:
            cur.append(ch)
    units.append("".join(cur))
    return units


# -- parameters and replies (the instrument's side) ------------------------------------------

def number_param(text: str, named: Mapping[str, float]) -> float:
    """A numeric parameter, or one of the names it may take instead (`{"MIN": lo, ...}`,
    matched on their first three letters); -104 if neither."""
    t = text.strip().upper()
    for key, value in named.items():
        if t.startswith(key[:3]):
            return float(value)
    try:
        return float(t)
    except ValueError:
        raise ExecError(-104, "Data type error") from None


def ranged_param(text: str, low: float, high: float, default: float) -> float:
    """A number within [low, high] that may also be MIN, MAX or DEFault; -222 outside."""
    value = number_param(text, {"MIN": low, "MAX": high, "DEF": default})
    if not low <= value <= high:
        raise ExecError(-222, "Data out of range")
    return value


def count_param(text: str, high: int, default: int = 1) -> int:
    """A count within [1, high] that may also be MIN, MAX or DEFault; -222 outside."""
    n = int(number_param(text, {"MIN": 1, "MAX": high, "DEF": default}))
    if not 1 <= n <= high:
        raise ExecError(-222, "Data out of range")
    return n


def bool_param(text: str) -> bool:
    """ON/1 or OFF/0; -224 otherwise."""
    t = text.strip().upper()
    if t in ("ON", "1"):
        return True
    if t in ("OFF", "0"):
        return False
    raise ExecError(-224, "Illegal parameter value")


def enum_param(text: str, choices: tuple[str, ...]) -> str:
    """Match a character parameter in short or long form; returns the short form."""
    t = text.strip().upper()
    for c in choices:
        if t in (short_form(c), c.upper()):
            return short_form(c)
    raise ExecError(-224, "Illegal parameter value")


def suffix_item(items: Mapping[int, T], args: Mapping[str, str], suffix: str = "channel") -> T:
    """What a header's numeric suffix selects (an omitted suffix is 1); -114 if nothing."""
    n = int(args.get(suffix) or 1)
    if n not in items:
        raise ExecError(-114, "Header suffix out of range")
    return items[n]


def nr3(value: float) -> str:
    """A number as the reply of a setting's query: `+1.000000000E+01`."""
    return f"{value:+.9E}"


def bool_reply(value: bool) -> str:
    """A boolean setting's query reply: 1 or 0."""
    return "1" if value else "0"
