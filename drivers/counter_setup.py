"""The counter's set-up (drivers/counter.py): its identity, the zero-mark input and the
timebase, each set and read back, so that a difference between the stand file and the
instrument refuses the run by stand key before anything is measured.

The lower class of the counter driver: `Counter` (drivers/counter.py) adds the
measurements, arm and fetch, on top of it.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Literal

from drivers.clock import Clock
from drivers.counter_profiles import CounterProfile, CounterWords
from drivers.scpi import IDN, Command, ErrorKinds, ScpiInstrument, ScpiValue
from drivers.time_tie import TimeTie

#: the family is bound in drivers.counter's name, where the driver has always raised it
COUNTER_ERRORS = ErrorKinds.family("Counter", "the counter", "drivers.counter")
(CounterError, CounterCommandError, CounterTimeout, CounterReplyError,
 CounterConnectionError) = COUNTER_ERRORS

What = Literal["edges", "periods"]


@dataclass(frozen=True)
class InputConfig:
    """How the zero-mark pulse enters the counter."""

    channel: int
    level_v: float
    slope: str
    coupling: str
    impedance_ohm: float


class CounterSetup(ScpiInstrument):
    """The counter as configured: its profile's words, the input, the timebase."""

    error_kinds = COUNTER_ERRORS
    words: CounterWords
    #: set by Counter.__init__ (drivers/counter.py)
    profile: CounterProfile
    time_tie: TimeTie
    #: every setting the measurement depends on, as the counter reads it back
    readback: dict[str, str]
    clock: Clock
    input: InputConfig | None

    def _check_identity(self) -> None:
        pattern = self.profile.idn_pattern
        idn = self.identify()
        if pattern and not re.search(pattern, idn, re.IGNORECASE):
            raise CounterError(f"{self.name}: *IDN? says {idn!r}, which is not a "
                               f"{self.profile.model} (expected /{pattern}/): check the "
                               f"stand file's counter model", command=IDN.text())

    @property
    def supports_timestamps(self) -> bool:
        return self.profile.supports_timestamps

    def template_values(self) -> dict[str, ScpiValue]:
        return {"channel": self.input.channel if self.input else 1}

    def identify(self) -> str:
        return self.ask(IDN)

    def configure(self, channel: int = 1, level_v: float | None = None, slope: str = "POS",
                  coupling: str = "DC", impedance_ohm: float = 1.0e6) -> InputConfig:
        """Set the input for the zero-mark pulse: an absolute trigger level, no auto-level.

        A once-per-revolution pulse is far below the auto-level's lowest frequency, so the
        level must be given (volts, e.g. half the sensor's output swing).
        """
        p = self.profile
        if level_v is None:
            raise CounterError(
                f"{self.name}: configure() needs level_v, an absolute trigger level in volts "
                "(a once-per-revolution pulse is too slow for the counter's auto-level)")
        problems = []
        if channel not in p.channels:
            problems.append(f"channel {channel!r} (has {p.channels})")
        if not p.level_range_v[0] <= float(level_v) <= p.level_range_v[1]:
            problems.append(f"level_v {level_v!r} (range {p.level_range_v[0]:g} .. "
                            f"{p.level_range_v[1]:g} V)")
        slope_u, coupling_u = str(slope).upper()[:3], str(coupling).upper()
        if slope_u not in p.slopes:
            problems.append(f"slope {slope!r} (one of {', '.join(p.slopes)})")
        if coupling_u not in p.couplings:
            problems.append(f"coupling {coupling!r} (one of {', '.join(p.couplings)})")
        if not any(math.isclose(float(impedance_ohm), z) for z in p.impedances_ohm):
            problems.append(f"impedance_ohm {impedance_ohm!r} (one of "
                            f"{', '.join(f'{z:g}' for z in p.impedances_ohm)})")
        if problems:
            raise CounterError(f"{self.name}: configure(): " + "; ".join(problems))
        self.input = InputConfig(int(channel), float(level_v), slope_u, coupling_u,
                                 float(impedance_ohm))
        with self.recovering():
            self._send_input()
            self._verify_input()
        return self.input

    def _method(self, what: What, method: str | None) -> str:
        p = self.profile
        if what == "edges":
            if not p.supports_timestamps:
                raise CounterError(f"{self.name}: the {p.model} cannot timestamp edges; "
                                   "use acquire_periods() / arm(what='periods')")
            return "timestamps"
        if what != "periods":
            raise ValueError(f"what must be 'edges' or 'periods', not {what!r}")
        available = (["timestamps"] if p.supports_timestamps else []) + \
            ([p.periods] if p.periods else [])
        if method is None:
            return available[0]
        if method not in available:
            raise CounterError(f"{self.name}: the {p.model} measures periods by "
                               f"{' or '.join(available)}, not {method!r}")
        return method

    def _send_input(self) -> None:
        w, c = self.words, self.input
        assert c is not None
        self.send(w.input_coupling, coupling=c.coupling)
        self.send(w.input_impedance, impedance_ohm=c.impedance_ohm)
        if w.input_level_auto is not None:
            self.send(w.input_level_auto, state=False)
        self.send(w.input_level, level_v=c.level_v)
        self.send(w.input_slope, slope=c.slope)

    def verify_reference(self, reference: str | None, timebase_limit_rel: float | None
                         ) -> str | None:
        """The timebase the stand's budget assumes, set (or read) and checked at connect.

        53220A/53230A User's Guide, "Time base" (p. 69 Agilent edition, p. 81 Keysight):
        `SENS:ROSC:SOUR EXT` (which also ends automatic selection), then
        `SENS:ROSC:EXT:CHEC ONCE` and `SYST:ERR?`: an error if no valid signal is at Ext
        Ref In. A model without a check word (the CNT-91: `ROSC:SOUR EXT`, see its
        profile's notes) relies on the selection's own error. `reference` is the stand's
        counter.reference ("external", "internal" or None: only read). A stand that claims a timebase limit below the model's own
        (counter.timebase_limit_rel) must run on an external reference.
        """
        w = self.words
        if w.reference_source is None:
            if reference is not None:
                raise CounterError(f"{self.name}: counter.reference: the {self.profile.model} "
                                   "profile has no reference-source word")
            return None
        with self.recovering():
            if reference is not None:
                source = "EXT" if reference == "external" else "INT"
                self.send(w.reference_source, source=source)
                if source == "EXT" and w.reference_check is not None:
                    self.send(w.reference_check, when="ONCE")  # an error if no signal
            got = self.query(w.reference_source.query_text()).strip()
        self.readback["counter.reference"] = got
        if reference is not None and not _same_setting(got, "EXT" if reference == "external"
                                                       else "INT"):
            raise CounterError(f"{self.name}: counter.reference: set {reference}, the counter "
                               f"reads back {got!r}")
        if (timebase_limit_rel is not None and timebase_limit_rel
                < self.profile.timebase_limit_rel and not _same_setting(got, "EXT")):
            raise CounterError(
                f"{self.name}: counter.timebase_limit_rel = {timebase_limit_rel:g} assumes an "
                f"external reference, but the counter runs on {got!r}; set "
                "counter.reference: external (and connect Ext Ref In)")
        return got

    def _verify_input(self) -> None:
        """Read every input setting back; a difference refuses the run by stand key."""
        w, c = self.words, self.input
        assert c is not None
        self._verify("counter.coupling", w.input_coupling, c.coupling)
        self._verify("counter.impedance_ohm", w.input_impedance, c.impedance_ohm)
        if w.input_level_auto is not None:
            self._verify("counter.level_auto", w.input_level_auto, False)
        self._verify("counter.level_v", w.input_level, c.level_v)
        self._verify("counter.slope", w.input_slope, c.slope)

    def _verify(self, key: str, word: Command | None, expected: ScpiValue | None) -> str | None:
        """Ask `word` back and compare with what was set; record it in `readback`."""
        if word is None:
            return None
        text = word.query_text(**self.template_values())
        got = self.query(text).strip()
        self.readback[key] = got
        if not _same_setting(got, expected):
            raise CounterError(f"{self.name}: {key}: set {expected!r}, the counter reads back "
                               f"{got!r} ({text}): the stand file and the instrument disagree",
                               command=text)
        return got


def _same_setting(reply: str, expected: ScpiValue | None) -> bool:
    """A read-back reply against the value set: numbers to 1e-9, booleans as 0/1/ON/OFF,
    words by their short form (`POS` for POSitive, `EXT` for EXTernal)."""
    text = reply.strip().strip('"').upper()
    if isinstance(expected, bool):
        return text in (("1", "ON") if expected else ("0", "OFF"))
    if isinstance(expected, (int, float)):
        try:
            return math.isclose(float(text), float(expected), rel_tol=1e-9, abs_tol=1e-12)
        except ValueError:
            return False
    want = str(expected).upper()
    return text.startswith(want[:3]) and want.startswith(text[:3])
