"""The frequency counter: the reference of the fixed-angle method (docs/method.md A1).

The counter times the zero-mark pulses, one per table revolution. What the engine wants
from it is N+1 consecutive edge timestamps (so N whole turns and exactly when they
happened, to cut the FOG record on the same turns), or, on a counter without timestamps,
N turn periods. The words differ per model (drivers/counter_profiles.py); the sequence
is the same:

    ABOR; CONF...; input (coupling, impedance, auto-level OFF, level, slope); FORM ASC;
    [timestamp rate, sample count, measurement timeout]; INIT; *OPC   -- arm()
    ... the engine does other things ...
    *ESR? until bit 0 (operation complete); FETC? ; SYST:ERR?           -- fetch()

Every configuring write is followed by `SYST:ERR?`, so an error names its command.
Waits are in real seconds and scale with the clock (a virtual stand runs up to `clock.speed`
times faster): a wait for n turns of period T allows n * T * (1 + slack) / min_speed(clock)
plus `timeout_margin_s`. The instrument's own measurement timeout (when the model has
one) is set to the same span in instrument seconds, so a missing signal comes back as
9.91E37 before the VISA timeout; either way the error is a `CounterTimeout`, and after
any failure the driver aborts the measurement, clears the error queue and checks with
`*OPC?` that the counter answers (reopening the link if it must), so the counter is idle
and ready for the next `arm()`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from drivers.clock import Clock, real_budget_s, stepped
from drivers.counter_profiles import (
    DEFAULT_TIMEOUT_MARGIN_S,
    CounterProfile,
    TimestampFormat,
    first_value_is_a_turn,
    get_profile,
    is_scpi_nan,
)
from drivers.counter_setup import (
    COUNTER_ERRORS,
    CounterCommandError,
    CounterConnectionError,
    CounterError,
    CounterReplyError,
    CounterSetup,
    CounterTimeout,
    InputConfig,
    What,
)
from drivers.scpi import (
    CLS,
    ESR_OPC,
    ESR_Q,
    OPC,
    OPC_Q,
    RST,
    SCPI_NAN,
    Command,
    InstrumentError,
    RawCallback,
    parse_numbers,
)
from drivers.time_tie import TimeTie, TimeTieAmbiguous
from drivers.transport import Transport

if TYPE_CHECKING:
    from drivers.counter_settings import CounterSettings

__all__ = ["COUNTER_ERRORS", "DEFAULT_COMMAND_TIMEOUT_S", "ESR_ERRORS", "SPAN_SLACK_REL",
           "Acquisition", "Counter", "CounterCommandError", "CounterConnectionError",
           "CounterError", "CounterMeasurementTimeout", "CounterReplyError", "CounterTimeout",
           "InputConfig", "What"]


# the family is declared at run time (ErrorKinds.family): mypy cannot see its classes
class CounterMeasurementTimeout(CounterTimeout):  # type: ignore[misc,valid-type]
    """The counter answered 9.91E37: no (or too few) edges within its own timeout."""


#: IEEE 488.2 ESR error bits: query (4), device-dependent (8), execution (16), command (32)
ESR_ERRORS = 0x3C

#: the measured span may exceed its nominal n * T by this fraction before we give up
SPAN_SLACK_REL = 0.25

DEFAULT_COMMAND_TIMEOUT_S = 2.0


@dataclass(frozen=True, eq=False)
class Acquisition:
    """One armed (and, once fetched, finished) measurement."""

    what: What
    method: str              # 'timestamps', 'init-fetch' or 'read'
    n: int                   # edges (what='edges') or periods asked for
    expected_period_s: float
    consecutive: bool        # periods are between consecutive zero marks
    armed_at_s: float        # clock time just after INIT (stand time on a twin)
    span_s: float            # longest credible duration, clock seconds (no margin)
    armed_real_s: float      # time.monotonic() then
    span_real_s: float       # longest credible duration, real seconds (no margin)
    deadline_real_s: float   # time.monotonic() by which the data must be there
    instrument_timeout_s: float | None
    #: the start event on the FOG's time axis and its standard uncertainty (time tie)
    t_start_s: float = 0.0
    t_start_u_s: float = 0.0
    values: np.ndarray | None = field(default=None)


class Counter(CounterSetup):
    """A SCPI frequency counter over pyvisa; see the module docstring for the sequence."""

    def __init__(self, resource: str, profile: CounterProfile, clock: Clock, *,
                 raw: RawCallback | None = None,
                 timeout_margin_s: float = DEFAULT_TIMEOUT_MARGIN_S,
                 command_timeout_s: float = DEFAULT_COMMAND_TIMEOUT_S,
                 visa_library: str = "@py", time_tie: TimeTie | None = None,
                 transport: Transport | None = None) -> None:
        self.profile = profile
        self.time_tie = time_tie or TimeTie()
        #: every setting the measurement depends on, as the counter reads it back
        self.readback: dict[str, str] = {}
        #: a first timestamp value seen clearly shorter than a turn: this counter stamps
        #: from its trigger (counter_profiles.first_value_is_a_turn)
        self._seen_from_start = False
        #: SYST:TIM as found at open (non-volatile on a 53230A): restored at close
        self._saved_timeout: str | None = None
        self.words = profile.words
        self.clock = clock
        self.timeout_margin_s = float(timeout_margin_s)
        self.recovery_commands = tuple(c for c in (profile.words.abort, CLS) if c is not None)
        self.input: InputConfig | None = None
        self._armed: Acquisition | None = None
        self.last_acquisition: Acquisition | None = None
        super().__init__(resource, visa_library=visa_library, raw=raw,
                         command_timeout_s=command_timeout_s,
                         name=f"counter {profile.model} at {resource}", transport=transport)

    @classmethod
    def from_settings(cls, settings: CounterSettings, clock: Clock, *,
                      raw: RawCallback | None = None) -> Counter:
        """Open the counter a stand's `counter:` block declares (drivers/counter_settings.py),
        the settings object whole, as python-can's `Bus(**config)`: a counter setting is
        read here, not copied field by field by each caller."""
        return cls.open(settings.resource, settings.model, clock, raw=raw,
                        time_tie=settings.time_tie or TimeTie(),
                        timeout_margin_s=settings.timeout_margin_s)

    @classmethod
    def open(cls, resource: str, model: str | CounterProfile, clock: Clock, *,
             raw: RawCallback | None = None,
             timeout_margin_s: float = DEFAULT_TIMEOUT_MARGIN_S,
             command_timeout_s: float = DEFAULT_COMMAND_TIMEOUT_S,
             visa_library: str = "@py", check_identity: bool = True,
             time_tie: TimeTie | None = None, transport: Transport | None = None) -> Counter:
        """Open the counter, bring it to a known idle state, check it is the model named,
        and note the measurement timeout it holds (restored at close)."""
        profile = get_profile(model) if isinstance(model, str) else model
        counter = cls(resource, profile, clock, raw=raw, timeout_margin_s=timeout_margin_s,
                      command_timeout_s=command_timeout_s, visa_library=visa_library,
                      time_tie=time_tie, transport=transport)
        try:
            with counter.recovering():
                counter.resync()
                counter.drain_errors()
                if check_identity:
                    counter._check_identity()
                if profile.words.measurement_timeout is not None:
                    counter._saved_timeout = counter.ask(profile.words.measurement_timeout)
        except BaseException:
            counter.close()
            raise
        return counter

    def __enter__(self) -> Counter:
        return self

    def close(self) -> None:
        """Abort a measurement still armed, restore the measurement timeout found at open
        (53220A/53230A Programmer's Reference p. 459: it is non-volatile, so a changed value
        would outlive the run), then close the link; all best effort."""
        if self._armed is not None and self.is_open and self.words.abort is not None:
            try:
                self.write(self.words.abort.text(), check=False)
            except InstrumentError:
                pass
        self._armed = None
        timeout_word = self.words.measurement_timeout
        if self._saved_timeout is not None and self.is_open and timeout_word is not None:
            try:
                self.send(timeout_word,
                          timeout_s=_timeout_param(self._saved_timeout))
            except InstrumentError:
                pass
        super().close()

    def reset(self) -> None:
        """*RST, *CLS, wait for completion. The input set-up is re-sent by the next arm()."""
        self._armed = None
        with self.recovering():
            self.write(RST.text())
            self.write(CLS.text(), check=False)
            self.query(OPC_Q.text())

    def arm(self, n: int, expected_period_s: float, *, what: What = "edges",
            method: str | None = None) -> Acquisition:
        """Start timing: n edges (timestamps) or n periods; `fetch()` returns them.

        `method` picks the periods' way on a model with more than one: 'timestamps'
        (differences of n+1 consecutive edges, the default where possible) or the model's
        period mode ('init-fetch' / 'read', whose readings are not consecutive turns).
        """
        if self.input is None:
            raise CounterError(f"{self.name}: arm() before configure(): the trigger level "
                               "is not set")
        if n < 1 or not expected_period_s > 0:
            raise ValueError(f"arm(n={n}, expected_period_s={expected_period_s}): need n >= 1 "
                             "and a positive period")
        method = self._method(what, method)
        n_read = n + 1 if (what == "periods" and method == "timestamps") else n
        limit = self.profile.max_count
        if method != "read" and n_read > limit:
            raise CounterError(f"{self.name}: {n_read} readings asked, the model holds "
                               f"{limit} per measurement")
        self._armed = None
        with self.recovering():
            acq = self._arm(what, method, n, n_read, float(expected_period_s))
        self._armed = acq
        return acq

    def fetch(self) -> np.ndarray:
        """Wait for the armed measurement (bounded) and return edges_s or periods_s."""
        acq = self._armed
        if acq is None:
            raise CounterError(f"{self.name}: fetch() without arm()")
        self._armed = None
        with self.recovering():
            values = self._fetch(acq)
        done = Acquisition(**{**acq.__dict__, "values": values})
        self.last_acquisition = done
        return values

    def acquire_edges(self, n_edges: int, expected_period_s: float) -> np.ndarray:
        """n_edges consecutive zero-mark timestamps on the counter's time axis, s."""
        self.arm(n_edges, expected_period_s, what="edges")
        return self.fetch()

    def acquire_periods(self, n: int, expected_period_s: float, *,
                        method: str | None = None) -> np.ndarray:
        """n turn periods, s: consecutive where the model timestamps (see `arm`)."""
        self.arm(n, expected_period_s, what="periods", method=method)
        return self.fetch()

    def _span_s(self, method: str, n_read: int, period_s: float) -> float:
        """Longest credible time for the readings, in instrument (virtual) seconds."""
        turns = {"timestamps": n_read,          # first edge within a turn, then n-1 turns
                 "init-fetch": 2 * n_read + 1,  # every other turn, plus the wait for a start
                 "read": 2}[method]             # per READ?: wait for a start, one turn
        return turns * period_s * (1.0 + SPAN_SLACK_REL)

    def _arm(self, what: What, method: str, n: int, n_read: int,
             period_s: float) -> Acquisition:
        w, p = self.words, self.profile
        if w.abort is not None:
            self.send(w.abort)
        if method == "timestamps":
            self.send(self._need(w.configure_timestamps, "configure_timestamps"), count=n_read)
        else:
            self.send(self._need(w.configure_period, "configure_period"))
        self._send_input()
        if w.format_data is not None:
            self.send(w.format_data, format="ASCii")
        tie = self.time_tie
        if method == "timestamps":
            if w.timestamp_info is not None:
                self.send(w.timestamp_info, state=True)
            if w.timestamp_rate is not None and p.timestamp_rate_hz:
                self.send(w.timestamp_rate, rate_hz=p.timestamp_rate_hz)
                self._verify("counter.timestamp_rate_hz", w.timestamp_rate, p.timestamp_rate_hz)
            if tie.uses_external_trigger and w.trigger_source is None:
                raise CounterError(f"{self.name}: the {p.model} profile has no trigger-source "
                                   "word, so the stand's time tie 'fog-sync' cannot be made")
        elif method == "init-fetch":
            if w.gate_time is not None:
                self.send(w.gate_time, gate_s="MIN")
            self.send(self._need(w.sample_count, "sample_count"), count=n_read)
        if w.trigger_source is not None and method != "read":
            external = method == "timestamps" and tie.uses_external_trigger
            source = p.external_trigger if external else "IMM"
            self.send(w.trigger_source, source=source)
            self._verify("counter.time_tie.source", w.trigger_source, source)
        span = self._span_s(method, n_read, period_s)
        if method == "timestamps" and tie.uses_external_trigger:
            span += tie.sync_period_s  # the wait for the first sync pulse
        inst_timeout = None
        if w.measurement_timeout is not None and p.measurement_timeout_range_s:
            # SYSTem:TIMeout bounds each reading, not the acquisition (Programmer's
            # Reference p. 459): one reading is at most a wait for a start edge and a turn
            lo, hi = p.measurement_timeout_range_s
            inst_timeout = max(2.0 * period_s * (1.0 + SPAN_SLACK_REL), lo)
            self.send(w.measurement_timeout,
                      timeout_s=inst_timeout if inst_timeout <= hi else "INFinity")
            inst_timeout = inst_timeout if inst_timeout <= hi else None
        real_span = span / self.clock.speed
        budget = real_budget_s(self.clock, span)  # a paced clock may run slower than speed
        t_start = t_start_u = 0.0
        if method == "read":  # READ? measures when asked: arm only configures
            real_span *= n_read
            budget *= n_read
        else:
            t_start, t_start_u = self._initiate()
            self.write(OPC.text(), check=False)
        now = time.monotonic()
        return Acquisition(
            what=what, method=method, n=n, expected_period_s=period_s,
            consecutive=(method == "timestamps" or p.periods_gap_free),
            armed_at_s=self.clock.now(), span_s=span, armed_real_s=now, span_real_s=real_span,
            deadline_real_s=now + budget + self.timeout_margin_s,
            instrument_timeout_s=inst_timeout, t_start_s=t_start, t_start_u_s=t_start_u)

    def _initiate(self, attempts: int = 8) -> tuple[float, float]:
        """INIT, bracketed by the clock; returns the start event on the FOG's axis.

        The checked write (INIT, then SYST:ERR?) returns once the counter has taken INIT,
        so INIT took effect inside [before, after]. With a fog-sync tie, a sync pulse
        inside that window makes the start ambiguous: abort and try again.
        """
        w = self.words
        init = self._need(w.initiate, "initiate")
        last: TimeTieAmbiguous | None = None
        for _ in range(attempts):
            before = self.clock.now()
            self.send(init)
            after = self.clock.now()
            try:
                return self.time_tie.start_s(before, after)
            except TimeTieAmbiguous as e:
                last = e
                if w.abort is not None:
                    self.send(w.abort)
        raise CounterError(f"{self.name}: the time tie stayed ambiguous over {attempts} "
                           f"INITs: {last}; is the host too slow for sync_period_s "
                           f"{self.time_tie.sync_period_s:g} s?", command=init.text())

    def _need(self, word: Command | None, role: str) -> Command:
        if word is None:
            raise CounterError(f"{self.name}: the {self.profile.model} profile has no "
                               f"{role} word")
        return word

    def _fetch(self, acq: Acquisition) -> np.ndarray:
        n_read = acq.n + 1 if (acq.what == "periods" and acq.method == "timestamps") else acq.n
        if acq.method == "read":
            values = self._read_periods(acq, n_read)
        else:
            self._wait_complete(acq)
            values = self._fetch_values(acq, n_read)
        self.check_errors("the measurement")
        if acq.what == "periods" and acq.method == "timestamps":
            return np.diff(values)
        return values

    def _read_periods(self, acq: Acquisition, n: int) -> np.ndarray:
        """One READ? per period, each allowed two turns (wait for a start, one turn)."""
        read = self._need(self.words.read, "read")
        per_read_s = real_budget_s(self.clock, self._span_s("read", 1, acq.expected_period_s))
        out = np.empty(n)
        for i in range(n):
            text = read.text()
            try:
                reply = self.query(text, timeout_s=per_read_s + self.timeout_margin_s)
            except CounterTimeout as e:
                raise CounterTimeout(f"{e} (reading {i + 1} of {n}, each waits for a start "
                                     f"edge and one turn of {acq.expected_period_s:.6g} s); "
                                     f"{self._signal_hint()}", command=text) from e
            value = self._numbers(text, reply, 1)
            self._refuse_nan(text, value, 1, acq)
            out[i] = value[0]
        return out

    def _wait_complete(self, acq: Acquisition) -> None:
        """Poll *ESR? for Operation Complete until the deadline (real seconds).

        Short polls, rather than one long blocking FETC?, keep every wait bounded by
        `command_timeout_s` and notice a lost link within that time. Polling starts at
        half the longest credible span (about when the data can first be there) and runs
        every 1/50 of it: a few dozen exchanges in the journal at most.
        """
        poll_s = min(max(acq.span_real_s / 50.0, 0.005), 2.0)
        poll_clock_s = min(max(acq.span_s / 50.0, 0.005), 2.0)
        clock_margin_s = self.timeout_margin_s  # clock s: a stepped clock runs no slower
        self.clock.sleep(acq.armed_at_s + 0.5 * acq.span_s - self.clock.now())
        while True:
            text = ESR_Q.text()
            reply = self.query(text)
            try:
                esr = int(float(reply))
            except ValueError as e:
                raise CounterReplyError(f"{self.name}: {text!r} replied {reply!r}",
                                        command=text, reply=reply.encode()) from e
            if esr & ESR_ERRORS:
                self.check_errors(f"the measurement (ESR {esr})")
            if esr & ESR_OPC:
                return
            if stepped(self.clock):  # co-simulation: the polls are on clock time
                if self.clock.now() > acq.armed_at_s + acq.span_s + clock_margin_s:
                    raise CounterTimeout(
                        f"{self.name}: {acq.n} {acq.what} at {acq.expected_period_s:.6g} s a "
                        f"turn not complete within {acq.span_s + clock_margin_s:.6g} s; "
                        f"{self._signal_hint()}",
                        command=self._need(self.words.initiate, "initiate").text())
                self.clock.sleep(poll_clock_s)
                continue
            if time.monotonic() > acq.deadline_real_s:
                raise CounterTimeout(
                    f"{self.name}: {acq.n} {acq.what} at {acq.expected_period_s:.6g} s a "
                    f"turn not complete within {acq.deadline_real_s - acq.armed_real_s:.3g} "
                    f"s (real); {self._signal_hint()}",
                    command=self._need(self.words.initiate, "initiate").text())
            time.sleep(poll_s)

    def _fetch_values(self, acq: Acquisition, n_read: int) -> np.ndarray:
        p = self.profile
        is_ts = acq.method == "timestamps"
        fmt = p.timestamp_format if is_ts else None
        per_result = (fmt.n_values(2) - fmt.n_values(1)) if fmt is not None else 1
        text, reply, values = self._fetch_numbers(n_read, per_result, fmt)
        if fmt is not None:
            try:
                since_start = fmt.decode(values)
            except ValueError as e:
                raise CounterReplyError(f"{self.name}: reply to {text!r}: {e}",
                                        command=text, reply=reply.encode()) from e
            nan = values[-n_read:] >= 0.999 * SCPI_NAN
            since_start[nan] = SCPI_NAN
            self._refuse_nan(text, since_start, n_read, acq)
            if fmt.name == "keysight-tst":
                self._check_first_value(text, values[1:], acq)
            elif fmt.name == "pendulum-stst":
                self._check_ts_origin(text, since_start, acq)
            if np.any(np.diff(since_start) <= 0):
                raise CounterReplyError(
                    f"{self.name}: the timestamps in the reply to {text!r} do not increase "
                    f"(first ones: {since_start[:4]})", command=text, reply=reply.encode())
            return acq.t_start_s + since_start
        self._refuse_nan(text, values, n_read, acq)
        return values

    def _check_first_value(self, text: str, intervals_s: np.ndarray,
                           acq: Acquisition) -> None:
        """The 53230A's first value: trigger to first edge, or (the Programmer's
        Reference's SENSe:TSTamp:RATE example) first edge to second, a full turn
        (counter_profiles, MANUAL_FIRST_VALUE). Only the first places the edges on the
        FOG's axis; a first value as long as a turn cannot be told from the second
        reading, so edges are refused rather than placed up to a turn wrong. Periods
        need no tie: every full-turn interval is one."""
        full = first_value_is_a_turn(intervals_s, acq.expected_period_s,
                                     self.profile.resolution_s, self._seen_from_start)
        self._seen_from_start = self._seen_from_start or not full
        self.readback["counter.first timestamp value"] = (
            "a full turn (edge to edge)" if full else "trigger to first edge")
        if full and acq.what == "edges":
            turn_s = float(np.median(intervals_s[1:])) if intervals_s.size > 1 \
                else acq.expected_period_s
            raise CounterError(
                f"{self.name}: the first value of the reply to {text!r} "
                f"({intervals_s[0]:.12g} s) is as long as the full turns after it "
                f"({turn_s:.12g} s): "
                "the counter stamps from its first edge, not from the trigger (as the "
                "53220A/53230A Programmer's Reference's SENSe:TSTamp:RATE example shows), so "
                "when the edges came after the trigger is unknown and they cannot be tied "
                "to the FOG's time axis (misplaced by up to a turn, harmonic phases "
                "wrong); refused. Periods (the rate) do not need the tie",
                command=text)

    def _check_ts_origin(self, text: str, since_start_s: np.ndarray,
                         acq: Acquisition) -> None:
        """The CNT-91's TS counts "since a certain start event that is not available for
        external control" (CNT-90 series Programmer's Handbook p. 8-72). The tie takes
        that event as the measurement's start (INIT, or the arming pulse of ARM:SOUR
        EXT4), after which the first stamped crossing comes within a turn; a first TS
        outside (0, a turn] counts from something else, and placing the edges by it would
        put them anywhere on the FOG's axis: refused for edges. Periods (differences of
        TS) do not need the tie."""
        first = float(since_start_s[0])
        turn = acq.expected_period_s * (1.0 + SPAN_SLACK_REL)
        ok = 0.0 < first <= turn
        self.readback["counter.first TS"] = f"{first:.12g} s"
        if ok or acq.what != "edges":
            return
        raise CounterError(
            f"{self.name}: the first time stamp of the reply to {text!r} is {first:.12g} s, "
            f"not within the first turn ({turn:.6g} s) after the measurement's start: the "
            "counter's TS does not count from the start this bench ties to the FOG's time "
            "axis (Programmer's Handbook p. 8-72: 'since a certain start event'), so the "
            "edges cannot be placed; refused. Periods (the rate) do not need the tie",
            command=text)

    def _fetch_numbers(self, n_read: int, per_result: int, fmt: TimestampFormat | None
                       ) -> tuple[str, str, np.ndarray]:
        """All readings: one FETC?, or FETC:ARR? in chunks of the model's limit (the
        CNT-91 gives at most 10 000 results a call, Programmer's Handbook p. 8-35; each
        call returns the next results)."""
        w, p = self.words, self.profile
        if w.fetch is not None:
            text = w.fetch.text()
            reply = self.query(text, timeout_s=self._transfer_s(n_read))
            n = fmt.n_values(n_read) if fmt is not None else n_read
            return text, reply, self._numbers(text, reply, n)
        array = self._need(w.fetch_array, "fetch")
        chunk = p.fetch_max_results or n_read
        parts, replies, text = [], [], ""
        for first in range(0, n_read, chunk):
            k = min(chunk, n_read - first)
            text = array.text(count=k)
            reply = self.query(text, timeout_s=self._transfer_s(k))
            parts.append(self._numbers(text, reply, k * per_result))
            replies.append(reply)
        return text, ",".join(replies), np.concatenate(parts)

    def _transfer_s(self, n: int) -> float:
        # transfer time: ~25 bytes a value; a slow link still moves 100 kB/s
        return self.command_timeout_s + n * 25 / 1e5

    def _numbers(self, text: str, reply: str, expected: int) -> np.ndarray:
        try:
            values = parse_numbers(reply)
        except ValueError as e:
            raise CounterReplyError(f"{self.name}: the reply to {text!r} is not a list of "
                                    f"numbers ({e}): {reply[:80]!r}", command=text,
                                    reply=reply.encode()) from e
        if values.size != expected:
            raise CounterReplyError(f"{self.name}: {text!r} returned {values.size} values, "
                                    f"expected {expected}", command=text,
                                    reply=reply.encode())
        return values

    def _signal_hint(self) -> str:
        c = self.input
        return (f"is the zero-mark signal reaching channel {c.channel if c else '?'} and "
                f"crossing {c.level_v if c else '?'} V?")

    def _refuse_nan(self, text: str, values: np.ndarray, n: int, acq: Acquisition) -> None:
        bad = is_scpi_nan(values)
        if bad.any():
            got = int(np.argmax(bad))
            limit = (f"its own timeout ({acq.instrument_timeout_s:.6g} s, instrument time)"
                     if acq.instrument_timeout_s else "its own timeout")
            raise CounterMeasurementTimeout(
                f"{self.name}: {text!r} returned 9.91E37 (measurement timeout): {got} of {n} "
                f"readings came before {limit}; {self._signal_hint()}", command=text)


def _timeout_param(reply: str) -> str:
    """A SYST:TIM? reply as the value to send back (9.9E37 means disabled: INFinity)."""
    try:
        value = float(reply)
    except ValueError:
        return reply.strip()
    return "INFinity" if value >= 9.8e37 else reply.strip()
