"""A small SCPI instrument base over pyvisa: commands as data, checked writes, one error path.

Why a base of our own rather than PyMeasure: the bench needs three things PyMeasure does
not give together: (1) every byte of every exchange handed to a `raw(direction, data)`
callback, so a run's journal can keep the instrument's own replies; (2) errors that name
the command that caused them and the instrument's message (SCPI error queue drained after
each checked write); (3) command words that live once, as data, shared by the driver that
sends them and by the simulated twin (sims/) that parses them.

Commands are written in SCPI mnemonic notation (IEEE 488.2 / SCPI-99 §6.2): upper case
is the short form, the whole word the long form; `[...]` is an optional node; `{name}` right
after a mnemonic is its numeric suffix (`INPut{channel}` renders as `INP1`). The driver sends
the short form; a server matches short or long forms, any case, with or without optional
nodes (`Command.match`). Parameters are a `str.format`-style template (`"({count}),(@{channel})"`)
that renders values for the driver and parses them back for a server (`Command.parse_params`);
placeholders carry no format spec: `format_value` renders every value the same way.

Properties can be declared as data on an instrument class, PyMeasure-style:

    class Dmm(ScpiInstrument):
        range_v = Control(Command("[SENSe:]VOLTage[:DC]:RANGe", "{value}"), cast=float,
                          validator=in_range(0.1, 1000))
        identity = Measurement(IDN)

A descriptor may name a word (a `str`) instead of a `Command`; it is then looked up in the
instance's `words` (a dataclass or mapping of Commands), so one driver class can serve
several instrument models whose words differ. Placeholders a descriptor does not set
(a channel, say) come from `instance.template_values()`.

Error classes: a driver family declares its own with `ErrorKinds.family("Counter", ...)`
and points `error_kinds` at them (see drivers/counter.py), so the base raises e.g.
`CounterTimeout` while callers may still catch the generic `InstrumentTimeout`.
"""

from __future__ import annotations

import contextlib
import numbers
import re
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, fields, is_dataclass
from functools import cached_property
from typing import (
    TYPE_CHECKING,
    ClassVar,
    Generic,
    NamedTuple,
    Self,
    TypeAlias,
    TypeVar,
    cast,
    overload,
)

from drivers.transport import (
    TranscriptMismatch,
    Transport,
    TransportTimeout,
    VisaTransport,
)

if TYPE_CHECKING:
    import numpy as np
    from _typeshed import DataclassInstance

RawCallback = Callable[[str, bytes], None]
#: a value a SCPI parameter is written from (`format_value`)
ScpiValue: TypeAlias = bool | int | float | str
#: a model's SCPI words by role: a dataclass of Commands (absent words None), or a mapping
Words: TypeAlias = "DataclassInstance | Mapping[str, Command | None]"

# -- commands as data -------------------------------------------------------------------

_TOKEN = re.compile(r"(\*?[A-Za-z][A-Za-z0-9]*)(\{(\w+)\})?")
_PLACEHOLDER = re.compile(r"\{(\w+)\}")
_OPTIONAL = re.compile(r"\[[^\]]*\]")


def short_form(mnemonic: str) -> str:
    """`TSTamp` -> `TST`: the leading capitals (and digits) of a SCPI mnemonic."""
    m = re.match(r"\*?[A-Z0-9]+", mnemonic)
    if not m:
        raise ValueError(f"SCPI mnemonic {mnemonic!r} has no upper-case short form")
    return m.group(0)


def format_value(value: ScpiValue) -> str:
    """A Python value as a SCPI parameter: bool -> ON/OFF, float -> NR3 with 12 digits."""
    if isinstance(value, bool):
        return "ON" if value else "OFF"
    if isinstance(value, numbers.Integral):       # numpy's integers too
        return str(int(value))
    if isinstance(value, numbers.Real):           # numpy's floats too
        return f"{float(value):.12G}"
    return str(value)


@dataclass(frozen=True)
class Command:
    """One SCPI command as data: the header in mnemonic notation and a parameter template.

    A header ending in `?` is a query only (`FETCh?`, `*IDN?`); any other header is a
    setting that `query_text()` can also ask back (`INP1:LEV?`).
    """

    header: str
    params: str = ""
    doc: str = ""

    @property
    def is_query(self) -> bool:
        return self.header.endswith("?")

    @cached_property
    def placeholders(self) -> tuple[str, ...]:
        """Names the header's suffixes and the parameter template need, in order."""
        names = [m.group(3) for m in _TOKEN.finditer(self.header) if m.group(3)]
        names += _PLACEHOLDER.findall(self.params)
        return tuple(dict.fromkeys(names))

    def _short_header(self, values: Mapping[str, ScpiValue]) -> str:
        def node(m: re.Match[str]) -> str:
            suffix = m.group(3)
            return short_form(m.group(1)) + (format_value(values[suffix]) if suffix else "")
        return _TOKEN.sub(node, _OPTIONAL.sub("", self.header))

    def _check_values(self, values: Mapping[str, ScpiValue], names: tuple[str, ...]) -> None:
        missing = [n for n in names if n not in values]
        if missing:
            raise KeyError(f"SCPI command {self.header!r} needs {', '.join(missing)}")

    def text(self, **values: ScpiValue) -> str:
        """The short-form program message the driver sends: `INP1:LEV 1.5`."""
        self._check_values(values, self.placeholders)
        head = self._short_header(values)
        if not self.params:
            return head
        formatted = {k: format_value(v) for k, v in values.items()}
        return f"{head} {self.params.format(**formatted)}"

    def query_text(self, **values: ScpiValue) -> str:
        """The query form: a query-only command as `text`, a setting with `?` appended."""
        if self.is_query:
            return self.text(**values)
        suffixes = tuple(m.group(3) for m in _TOKEN.finditer(self.header) if m.group(3))
        self._check_values(values, suffixes)
        return self._short_header(values) + "?"

    # -- the server's side: match a received header, parse its parameters -------------
    @cached_property
    def _header_regex(self) -> re.Pattern[str]:
        body = self.header.removesuffix("?")
        out: list[str] = []
        pos = 0
        for m in _TOKEN.finditer(body):
            out.append(_punctuation_regex(body[pos:m.start()]))
            mnemonic, suffix = m.group(1), m.group(3)
            short, long = short_form(mnemonic), mnemonic.upper()
            out.append(re.escape(short) if short == long
                       else f"(?:{re.escape(long)}|{re.escape(short)})")
            if suffix:
                out.append(f"(?P<{suffix}>\\d*)")
            pos = m.end()
        out.append(_punctuation_regex(body[pos:]))
        q = r"\?" if self.is_query else ""
        return re.compile(f"^:?{''.join(out)}{q}$", re.IGNORECASE)

    def match(self, header: str, *, query: bool | None = None) -> dict[str, str] | None:
        """Match a received header (`:INPut1:LEVel:ABS`); returns its suffixes or None.

        For a setting, `query=True` matches its query form (`INP1:LEV?`). An omitted suffix
        comes back as "" (SCPI: the default, usually 1).
        """
        if query is None:
            query = self.is_query
        if self.is_query and not query:
            return None
        text = header.strip()
        if query and not self.is_query:
            if not text.endswith("?"):
                return None
            text = text[:-1]
        m = self._header_regex.match(text)
        return None if m is None else dict(m.groupdict())

    @cached_property
    def _params_regex(self) -> re.Pattern[str]:
        out: list[str] = []
        pos = 0
        template = re.sub(r"\s+", "", self.params)
        for m in _PLACEHOLDER.finditer(template):
            out.append(re.escape(template[pos:m.start()]))
            out.append(f"(?P<{m.group(1)}>[^,()]+?)")
            pos = m.end()
        out.append(re.escape(template[pos:]))
        return re.compile(f"^{''.join(out)}$")

    def parse_params(self, text: str) -> dict[str, str]:
        """Parameters of a received command as strings, by placeholder name.

        Raises `ParameterError` with the SCPI code a server should queue: -109 missing,
        -108 not allowed (no parameter expected, or more than the command takes:
        SCPI-99 vol. 2, 21.8.9, "more parameters were received than expected for the
        header"), -102 syntax.
        """
        text = re.sub(r"\s+", "", text)
        if not self.params:
            if text:
                raise ParameterError(-108, "Parameter not allowed")
            return {}
        if not text:
            raise ParameterError(-109, "Missing parameter")
        m = self._params_regex.match(text)
        if m is None:
            if count_params(text) > count_params(self.params):
                raise ParameterError(-108, "Parameter not allowed")
            raise ParameterError(-102, "Syntax error")
        return dict(m.groupdict())


def count_params(text: str) -> int:
    """How many parameters a parameter text holds: its commas outside parentheses
    (a channel list `(@1,2)` is one parameter) and quotes, plus one; 0 if empty."""
    if not text.strip():
        return 0
    depth, quote, n = 0, "", 1
    for ch in text:
        if quote:
            quote = "" if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch == "(":
            depth += 1
        elif ch == ")":
            depth = max(depth - 1, 0)
        elif ch == "," and depth == 0:
            n += 1
    return n


def _punctuation_regex(text: str) -> str:
    """The bits between mnemonics: ':' and optional-node brackets."""
    return text.replace("[", "(?:").replace("]", ")?").replace("*", r"\*")


class ParameterError(ValueError):
    """A received parameter does not fit its command (a server queues `code`)."""

    def __init__(self, code: int, message: str) -> None:
        super().__init__(message)
        self.code = code
        self.message = message


# IEEE 488.2 common commands and the SCPI words every instrument here shares
IDN = Command("*IDN?", doc="identity: maker, model, serial, firmware")
RST = Command("*RST", doc="reset to the factory state")
CLS = Command("*CLS", doc="clear status and the error queue")
OPC_Q = Command("*OPC?", doc="1 once every pending operation has completed")
OPC = Command("*OPC", doc="set ESR bit 0 once every pending operation has completed")
ESR_Q = Command("*ESR?", doc="read and clear the standard event status register")
WAI = Command("*WAI", doc="wait for pending operations before the next command")
SYST_ERR = Command("SYSTem:ERRor[:NEXT]?", doc="next entry of the error queue")
ABORT = Command("ABORt", doc="abort a measurement in progress; trigger system to idle")
TRG = Command("*TRG", doc="bus trigger (IEEE 488.2 10.37): a measurement waiting for a BUS "
                          "trigger starts")
INIT = Command("INITiate[:IMMediate]", doc="start a measurement (overlapped)")

#: ESR bit 0: Operation Complete (IEEE 488.2 §11.5.1)
ESR_OPC = 0x01

#: SCPI's "not a number" (SCPI-99 §7.2.1): what a counter returns for a timed-out reading
SCPI_NAN = 9.91e37


# -- replies -------------------------------------------------------------------------------

_ERROR_ENTRY = re.compile(r'^\s*([+-]?\d+)\s*,\s*"(.*)"\s*$')


@dataclass(frozen=True)
class ErrorEntry:
    """One entry of a SCPI error queue: `-113,"Undefined header"`."""

    code: int
    message: str

    @classmethod
    def parse(cls, text: str) -> ErrorEntry:
        m = _ERROR_ENTRY.match(text)
        if m is None:  # a late data reply must not pass for an error entry
            raise ValueError(f"not a SCPI error entry: {text[:80]!r}")
        return cls(int(m.group(1)), m.group(2))

    def __str__(self) -> str:
        return f'{self.code},"{self.message}"'


def parse_numbers(text: str) -> np.ndarray:
    """A comma-separated list of SCPI numbers (NR1/NR2/NR3, `+1.0E-006` too)."""
    parts = text.strip().split(",")
    if any(not p.strip() for p in parts):
        raise ValueError(f"empty field in {text[:80]!r}")
    import numpy as np  # here, not at load: the counter's models are read without numpy

    return np.asarray(parts, dtype=float)  # numpy parses the strings (and refuses junk)


# -- errors ---------------------------------------------------------------------------------

class InstrumentError(Exception):
    """Anything an instrument (or the way to it) did wrong; names the command involved."""

    def __init__(self, message: str, *, command: str | None = None) -> None:
        super().__init__(message)
        self.command = command


class InstrumentCommandError(InstrumentError):
    """The instrument's error queue reported errors after a command."""

    def __init__(self, message: str, *, command: str | None = None,
                 errors: tuple[ErrorEntry, ...] = ()) -> None:
        super().__init__(message, command=command)
        self.errors = errors


class InstrumentTimeout(InstrumentError):
    """No (complete) reply within the time allowed."""


class InstrumentReplyError(InstrumentError):
    """A reply that cannot be what the command asks for."""

    def __init__(self, message: str, *, command: str | None = None, reply: bytes = b"") -> None:
        super().__init__(message, command=command)
        self.reply = reply


class InstrumentConnectionError(InstrumentError):
    """The connection failed or was lost."""


E = TypeVar("E", bound=InstrumentError)


class ErrorKinds(NamedTuple):
    """Which exception classes a driver family raises for each kind of failure (a named
    tuple, so unpacking it keeps each class's type)."""

    #: the family's own root, which every kind below also derives from
    base: type[InstrumentError] = InstrumentError
    command: type[InstrumentCommandError] = InstrumentCommandError
    timeout: type[InstrumentTimeout] = InstrumentTimeout
    reply: type[InstrumentReplyError] = InstrumentReplyError
    connection: type[InstrumentConnectionError] = InstrumentConnectionError

    @classmethod
    def family(cls, prefix: str, what: str, module: str) -> ErrorKinds:
        """A driver family's exceptions, declared once: `<prefix>Error`, the family's root,
        and `<prefix>CommandError`, `<prefix>Timeout`, `<prefix>ReplyError`,
        `<prefix>ConnectionError`, each also the generic kind, so a caller may catch
        `CounterTimeout` or any `InstrumentTimeout`. `what` names the instrument in their
        docstrings ("the counter"); `module` is the `__name__` of the module that binds
        the names (tracebacks show them there). Iterating gives root, command, timeout,
        reply, connection: `(CounterError, ...) = COUNTER_ERRORS`.
        """
        def declare(suffix: str, kind: type[E], doc: str) -> type[E]:
            bases = (kind,) if kind is InstrumentError else (base, kind)
            # type() makes a subclass of `kind`, which mypy cannot follow
            return cast("type[E]", type(f"{prefix}{suffix}", bases,
                                        {"__doc__": doc, "__module__": module}))

        the = what[:1].upper() + what[1:]
        base = declare("Error", InstrumentError, f"Anything {what}, or the way to it, did wrong.")
        return cls(
            command=declare("CommandError", InstrumentCommandError,
                            f"{the}'s error queue reported an error (the message names the "
                            "command)."),
            timeout=declare("Timeout", InstrumentTimeout, f"{the} did not answer in time."),
            reply=declare("ReplyError", InstrumentReplyError,
                          "A reply that cannot be the data asked for (garbage, wrong count, "
                          "out of order)."),
            connection=declare("ConnectionError", InstrumentConnectionError,
                               f"The link to {what} failed or was lost."),
            base=base)



# -- the instrument -------------------------------------------------------------------------

class ScpiInstrument:
    """One SCPI instrument behind a VISA resource, with a journal of every byte.

    `write` checks the error queue after the command by default (one `SYST:ERR?` round
    trip), so an error names the exact command that caused it. `query` that gets no reply
    drains the error queue before calling it a timeout: an undefined query header makes a
    SCPI instrument queue -113 and say nothing, and the -113 is the useful message.
    After any failure, `recover()` brings the instrument back to a known state.
    """

    error_kinds: ClassVar[ErrorKinds] = ErrorKinds()
    #: sent by `recover()` before `*OPC?`: end any measurement, clear status
    recovery_commands: tuple[Command, ...] = (CLS,)
    #: the model's SCPI words by role (a dataclass or mapping of Commands); a driver
    #: narrows the type
    words: Words | None = None
    #: the last `recover()` had to reopen the link
    reopened: bool = False

    def __init__(self, resource: str, *, visa_library: str = "@py", raw: RawCallback | None = None,
                 command_timeout_s: float = 2.0, name: str | None = None,
                 read_termination: str = "\n", write_termination: str = "\n",
                 error_query: Command = SYST_ERR, transport: Transport | None = None) -> None:
        self.resource = resource
        self.visa_library = visa_library
        self.raw = raw
        self.command_timeout_s = float(command_timeout_s)
        self.name = name or resource
        self.read_termination = read_termination
        self.write_termination = write_termination
        self.error_query = error_query
        self._lock = threading.RLock()
        #: the first command since which the error queue has not been read (None: clean)
        self._unchecked_since: str | None = None
        #: a transport given by the caller (a transcript): used as is, never reopened
        self._given = transport
        self._inst: Transport | None = None
        self.connect()

    # -- connection ---------------------------------------------------------------------
    def connect(self) -> None:
        if self._given is not None:
            self._inst = self._given
            return
        try:
            self._inst = VisaTransport(
                self.resource, visa_library=self.visa_library,
                read_termination=self.read_termination,
                write_termination=self.write_termination, timeout_s=self.command_timeout_s)
        except Exception as e:  # pyvisa raises VisaIOError, OSError, ValueError ...
            self._inst = None
            raise self.error_kinds.connection(
                f"{self.name}: cannot open VISA resource {self.resource!r} "
                f"(library {self.visa_library!r}): {e}") from e

    def reconnect(self) -> None:
        self._drop_session()
        self.connect()

    def _drop_session(self) -> None:
        inst, self._inst = self._inst, None
        if inst is not None and inst is not self._given:
            with contextlib.suppress(Exception):
                inst.close()

    def close(self) -> None:
        with self._lock:
            self._drop_session()
            if self._given is not None:
                self._given.close()

    @property
    def is_open(self) -> bool:
        return self._inst is not None

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- bytes ----------------------------------------------------------------------------
    def _require(self) -> Transport:
        if self._inst is None:
            raise self.error_kinds.connection(f"{self.name}: not connected")
        return self._inst

    def _tx(self, text: str) -> None:
        data = (text + self.write_termination).encode("ascii")
        inst = self._require()
        if self.raw:
            self.raw("tx", data)
        try:
            inst.write(data)
        except TranscriptMismatch:
            raise
        except Exception as e:
            raise self.error_kinds.connection(
                f"{self.name}: writing {text!r} failed: {e}", command=text) from e

    def _rx(self, command: str, timeout_s: float) -> str:
        inst = self._require()
        try:
            data = inst.read(timeout_s)
        except TransportTimeout as e:
            raise self.error_kinds.timeout(
                f"{self.name}: no reply to {command!r} within {timeout_s:.3g} s",
                command=command) from e
        except Exception as e:
            raise self.error_kinds.connection(
                f"{self.name}: reading the reply to {command!r} failed: {e}",
                command=command) from e
        if self.raw:
            self.raw("rx", data)
        try:
            return data.decode("ascii").rstrip("\r\n")
        except UnicodeDecodeError as e:
            raise self.error_kinds.reply(
                f"{self.name}: the reply to {command!r} is not ASCII: {_show(data)}",
                command=command, reply=data) from e

    # -- text -----------------------------------------------------------------------------
    def write(self, text: str, *, check: bool = True) -> None:
        """Send one program message; with `check`, raise if the error queue then holds any.

        Errors queued since an unchecked command are drained first and named as such:
        they are not blamed on this command. *CLS empties the queue (IEEE 488.2 10.3), so
        after it there is nothing to blame.
        """
        with self._lock:
            clears = text.lstrip().upper().startswith("*CLS")
            if not check:
                self._tx(text)
                self._unchecked_since = None if clears else (self._unchecked_since or text)
                return
            earlier: list[ErrorEntry] = []
            since = self._unchecked_since
            if since is not None and not clears:
                earlier = self.drain_errors()
            self._unchecked_since = None
            self._tx(text)
            errors = self.drain_errors()
            if earlier or errors:
                parts = []
                if errors:
                    parts.append(f"after {text!r} the instrument reported "
                                 + "; ".join(str(e) for e in errors))
                if earlier:
                    parts.append(f"before {text!r} its error queue already held "
                                 + "; ".join(str(e) for e in earlier)
                                 + f" (from {since!r} or later, or the instrument itself)")
                raise self.error_kinds.command(f"{self.name}: " + "; ".join(parts),
                                               command=text, errors=tuple(errors + earlier))

    def query(self, text: str, *, timeout_s: float | None = None) -> str:
        """Send a query and read its reply (one line, terminator removed).

        A query does not mark the error queue unchecked: a query the instrument cannot
        answer gives no reply, and that silence is where its error is read
        (`_errors_after_silence`). Only an unchecked write leaves the queue to be drained
        before the next checked one, so the manuals' transcripts keep one SYST:ERR? per
        setting.
        """
        with self._lock:
            try:
                return self._exchange(text, timeout_s)
            except InstrumentTimeout as e:
                errors = self._errors_after_silence()
                if errors:
                    raise self.error_kinds.command(
                        f"{self.name}: {text!r} got no reply; the instrument reported "
                        + "; ".join(str(x) for x in errors), command=text,
                        errors=tuple(errors)) from e
                raise

    def _exchange(self, text: str, timeout_s: float | None = None) -> str:
        self._tx(text)
        return self._rx(text, self.command_timeout_s if timeout_s is None else timeout_s)

    def send(self, command: Command | str, *, check: bool = True, **values: ScpiValue) -> str:
        """Send a word (a Command, or a name in `self.words`); returns the text sent."""
        cmd = self.word(command)
        text = cmd.text(**{**self.template_values(), **values})
        self.write(text, check=check)
        return text

    def ask(self, command: Command | str, *, timeout_s: float | None = None,
            **values: ScpiValue) -> str:
        """Query a word: a query-only command as is, a setting in its `?` form."""
        cmd = self.word(command)
        return self.query(cmd.query_text(**{**self.template_values(), **values}),
                          timeout_s=timeout_s)

    def word(self, command: Command | str) -> Command:
        if isinstance(command, Command):
            return command
        words = self.words
        found: Command | None = (words.get(command) if isinstance(words, Mapping)
                 else getattr(words, command, None))
        if found is None:
            raise self.error_kinds.command(
                f"{self.name}: this instrument has no word {command!r}", command=command)
        return found

    def template_values(self) -> dict[str, ScpiValue]:
        """Default placeholder values for words (e.g. the channel); drivers override."""
        return {}

    def identify(self) -> str:
        """The instrument's `*IDN?` reply: maker, model, serial, firmware."""
        return self.ask(IDN)

    # -- the error queue ------------------------------------------------------------------
    def next_error(self) -> ErrorEntry:
        text = self.error_query.text()
        reply = self._exchange(text)
        try:
            return ErrorEntry.parse(reply)
        except ValueError as e:
            raise self.error_kinds.reply(
                f"{self.name}: {text!r} replied {reply!r}, not an error entry",
                command=text, reply=reply.encode()) from e

    def drain_errors(self, limit: int = 32) -> list[ErrorEntry]:
        """Read the error queue until `0,"No error"` (at most `limit` entries)."""
        out: list[ErrorEntry] = []
        for _ in range(limit):
            e = self.next_error()
            if e.code == 0:
                break
            out.append(e)
        return out

    def check_errors(self, after: str) -> None:
        errors = self.drain_errors()
        self._unchecked_since = None
        if errors:
            raise self.error_kinds.command(
                f"{self.name}: after {after!r} the instrument reported "
                + "; ".join(str(e) for e in errors), command=after, errors=tuple(errors))

    def _errors_after_silence(self) -> list[ErrorEntry]:
        """After a query went unanswered: what does the error queue say? ([] if unsure)."""
        try:
            self._clear_input()
            return self.drain_errors()
        except InstrumentError:
            return []

    def _clear_input(self) -> None:
        """Device clear, where the interface has one (see `VisaTransport.clear`); late
        replies on a raw socket are skipped by `resync`."""
        if self._inst is not None:
            with contextlib.suppress(Exception):
                self._inst.clear()

    # -- known state ------------------------------------------------------------------------
    def resync(self, timeout_s: float | None = None) -> list[str]:
        """Clear, send `recovery_commands`, then `*OPC?` and read until its `1`.

        Returns the stale lines read on the way (late replies). Raises on failure.
        """
        timeout_s = self.command_timeout_s if timeout_s is None else timeout_s
        with self._lock:
            self._clear_input()
            for cmd in self.recovery_commands:
                self._tx(cmd.text())
                if cmd.text().upper().startswith("*CLS"):
                    self._unchecked_since = None     # the queue is empty now
            text = OPC_Q.text()
            self._tx(text)
            stale: list[str] = []
            deadline = time.monotonic() + timeout_s
            while True:
                line = self._rx(text, max(deadline - time.monotonic(), 0.001))
                if line.strip() in ("1", "+1"):
                    return stale
                stale.append(line)
                if len(stale) > 16 or time.monotonic() > deadline:
                    raise self.error_kinds.reply(
                        f"{self.name}: no '1' in reply to {text!r} after {len(stale)} lines",
                        command=text, reply=line.encode())

    def recover(self) -> str:
        """Bring the instrument to a known idle state; reconnect if the link is gone.

        Returns a sentence saying what was done (for the exception's notes and the log).
        Raises the connection error kind if neither works.
        """
        with self._lock:
            self.reopened = False
            if self._inst is not None:
                try:
                    stale = self.resync()
                    extra = f", {len(stale)} stale line(s) discarded" if stale else ""
                    return f"{self.name}: recovered: {self._recovery_words()}, idle{extra}"
                except InstrumentError:
                    pass
            try:
                self.reconnect()
                self.reopened = True
                self.resync()
            except InstrumentError as e:
                self._drop_session()
                raise self.error_kinds.connection(
                    f"{self.name}: cannot bring the instrument back to a known state: {e}"
                ) from e
            return (f"{self.name}: the link had to be reopened; recovered: "
                    f"{self._recovery_words()}, idle")

    def _recovery_words(self) -> str:
        return ", ".join(c.text() for c in self.recovery_commands) + " sent"

    @contextlib.contextmanager
    def recovering(self) -> Iterator[None]:
        """On an instrument error inside, recover and note how; a lost link becomes a
        connection error (a timeout that needed a reconnect was a dropped link)."""
        try:
            yield
        except InstrumentError as e:
            try:
                note = self.recover()
            except InstrumentConnectionError as e2:
                if isinstance(e, InstrumentConnectionError):
                    e.add_note(str(e2))
                    raise
                raise self.error_kinds.connection(
                    f"{e} -- and then: {e2}", command=e.command) from e
            if self.reopened and isinstance(e, InstrumentTimeout):
                lost = self.error_kinds.connection(
                    f"{e}: the link was lost (it had to be reopened)", command=e.command)
                lost.add_note(note)
                raise lost from e
            e.add_note(note)
            raise


def _show(data: bytes, limit: int = 60) -> str:
    shown = repr(data[:limit])
    return shown + (f" ... ({len(data)} bytes)" if len(data) > limit else "")


# -- properties as data -------------------------------------------------------------------

T = TypeVar("T", bound=ScpiValue)
C = TypeVar("C")


class _Descriptor(Generic[T]):
    def __init__(self, doc: str = "") -> None:
        self.__doc__ = doc
        self.name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name


class Measurement(_Descriptor[T]):
    """A read-only property: a query, its reply cast (`str`, `float`, `parse_numbers`)."""

    def __init__(self, command: Command | str, cast: Callable[[str], T] = str,  # type: ignore[assignment]
                 doc: str = "") -> None:
        super().__init__(doc or (command.doc if isinstance(command, Command) else ""))
        self.command = command
        self.cast = cast

    @overload
    def __get__(self, inst: None, owner: type) -> Self: ...
    @overload
    def __get__(self, inst: ScpiInstrument, owner: type) -> T: ...

    def __get__(self, inst: ScpiInstrument | None, owner: type) -> Self | T:
        if inst is None:
            return self
        return self.cast(inst.ask(self.command))


class Setting(_Descriptor[T]):
    """A write-only property: `validator` checks (and may convert) before sending.

    The value fills the command's one placeholder not given by `template_values()`.
    """

    def __init__(self, command: Command | str, validator: Callable[[T], T] | None = None,
                 doc: str = "") -> None:
        super().__init__(doc or (command.doc if isinstance(command, Command) else ""))
        self.set_command = command
        self.validator = validator

    def __set__(self, inst: ScpiInstrument, value: T) -> None:
        if self.validator is not None:
            try:
                value = self.validator(value)
            except (ValueError, TypeError) as e:
                raise ValueError(f"{inst.name}: {self.name} = {value!r}: {e}") from e
        cmd = inst.word(self.set_command)
        given = inst.template_values()
        free = [n for n in cmd.placeholders if n not in given]
        if len(free) != 1:
            raise TypeError(f"{cmd.header!r}: a Setting needs exactly one free placeholder, "
                            f"has {free}")
        inst.write(cmd.text(**{**given, free[0]: value}))


class Control(Setting[T]):
    """A read-write property: the setting, and its query form (or a separate query)."""

    def __init__(self, command: Command | str, cast: Callable[[str], T] = str,  # type: ignore[assignment]
                 validator: Callable[[T], T] | None = None,
                 get_command: Command | str | None = None, doc: str = "") -> None:
        super().__init__(command, validator, doc)
        self.get_command = get_command or command
        self.cast = cast

    @overload
    def __get__(self, inst: None, owner: type) -> Self: ...
    @overload
    def __get__(self, inst: ScpiInstrument, owner: type) -> T: ...

    def __get__(self, inst: ScpiInstrument | None, owner: type) -> Self | T:
        if inst is None:
            return self
        return self.cast(inst.ask(self.get_command))


def in_range(low: float, high: float) -> Callable[[float], float]:
    """Validator: a number within [low, high]."""
    def check(value: float) -> float:
        v = float(value)
        if not low <= v <= high:
            raise ValueError(f"must be within [{low:g}, {high:g}]")
        return v
    return check


def one_of(*choices: C) -> Callable[[C], C]:
    """Validator: one of the given values (strings compared case-insensitively)."""
    def check(value: C) -> C:
        for c in choices:
            if (isinstance(c, str) and isinstance(value, str) and c.upper() == value.upper()) \
                    or c == value:
                return c
        raise ValueError(f"must be one of {', '.join(map(str, choices))}")
    return check


def words_of(words: Words | None) -> dict[str, Command]:
    """The Commands of a words dataclass (or mapping), by name, skipping absent ones."""
    if isinstance(words, Mapping):
        return {k: v for k, v in words.items() if isinstance(v, Command)}
    if is_dataclass(words):
        return {f.name: getattr(words, f.name) for f in fields(words)
                if isinstance(getattr(words, f.name), Command)}
    raise TypeError(f"words must be a dataclass or mapping of Commands, not {type(words)}")
