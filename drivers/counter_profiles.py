"""Frequency-counter models as data: their SCPI words, reply formats and metrology.

One `CounterProfile` per model. The driver (drivers/counter.py) sends these words; the
twin (sims/counter_twin.py) parses the same objects, so a word lives here once. A word a
model lacks is `None`; the driver then uses another way or says the model cannot.

Metrology (docs/method.md A1: dT = sqrt(d_counter^2 + d_trigger^2)): each profile carries what
the error budget needs of the counter: the single-shot error of one timestamp, the
reading's resolution (the twin quantises to it) and the timebase's fractional frequency
limit. The figures are the datasheets' as we know them, to be replaced by the numbers of
the calibration certificate of the counter actually used (`dataclasses.replace`).

Where we were unsure of the real command syntax, the profile's `notes` says so; every
unsure word is one that a real instrument would reject with -113 at `configure()` or
`arm()`, by name, so a wrong guess is found on the first connection, not in a result.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from drivers.scpi import ABORT, INIT, SCPI_NAN, Command
from drivers.waits import MIN_REAL_MARGIN_S

if TYPE_CHECKING:
    import numpy as np

#: the counter's default margin on its measurement timeouts: the bench's stated minimum
#: (drivers/waits.py); here, with the models, so that the settings read it without numpy
DEFAULT_TIMEOUT_MARGIN_S = MIN_REAL_MARGIN_S


@dataclass(frozen=True)
class CounterWords:
    """The SCPI words of one counter model, by role (None: the model has no such word)."""

    # input conditioning (absolute level: a once-per-rev pulse is too slow for auto-level)
    input_coupling: Command = Command("INPut{channel}:COUPling", "{coupling}",
                                      doc="AC or DC")
    input_impedance: Command = Command("INPut{channel}:IMPedance", "{impedance_ohm}",
                                       doc="50 or 1E6 ohm")
    input_level_auto: Command | None = Command("INPut{channel}:LEVel:AUTO", "{state}",
                                               doc="auto-level OFF")
    input_level: Command = Command("INPut{channel}:LEVel[:ABSolute]", "{level_v}",
                                   doc="absolute trigger level, V")
    input_slope: Command = Command("INPut{channel}:SLOPe", "{slope}", doc="POS or NEG")
    # measurement set-up
    configure_timestamps: Command | None = None
    configure_period: Command | None = None
    timestamp_rate: Command | None = None
    timestamp_info: Command | None = None
    trigger_source: Command | None = None
    reference_source: Command | None = None
    reference_check: Command | None = None
    sample_count: Command | None = None
    gate_time: Command | None = None
    measurement_timeout: Command | None = None
    format_data: Command | None = Command("FORMat[:DATA]", "{format}", doc="ASCii")
    # running it
    abort: Command | None = ABORT
    initiate: Command | None = INIT
    fetch: Command | None = None
    fetch_array: Command | None = None
    read: Command | None = None


# -- reply formats: how each model lays out its data (decode for the driver, encode for
#    the twin; one place, so they cannot drift apart) ------------------------------------

def nr3(value: float, digits: int = 15, exp_digits: int = 2) -> str:
    """A SCPI NR3 number: `+3.600000000000000E-01` (Keysight prints 3 exponent digits)."""
    mantissa, exp = f"{value:+.{digits}E}".split("E")
    return f"{mantissa}E{int(exp):+0{exp_digits + 1}d}"


class TimestampFormat:
    """How a model lays out N timestamps in its reply.

    `decode` gives the edges as times since the measurement's start event (the trigger
    that began it), which no reply carries on any other axis: placing them on the FOG's
    time axis is the time tie's job (drivers/time_tie.py).
    """

    name = ""

    def encode(self, edges_s: np.ndarray, t_start_s: float, digits: int,
               exp_digits: int, first_index: int = 0) -> str:
        """The twin's reply for edges at `edges_s`, the start event at `t_start_s`;
        `first_index` is the first edge's place in the acquisition (a later chunk)."""
        raise NotImplementedError

    def decode(self, values: np.ndarray) -> np.ndarray:
        """Edge times since the start event; raises ValueError saying what is wrong."""
        raise NotImplementedError

    def n_values(self, n_edges: int) -> int:
        raise NotImplementedError


class KeysightTimestamps(TimestampFormat):
    """53230A `CONF:ARR:TST`: the prescaler, then `count` intervals, not edge times.

    53220A/53230A Programmer's Reference, MEASure:ARRay:TSTamp? (p. 240, "Return Format":
    the prescaler, then the measurements) and SENSe:TSTamp:RATE (p. 377, typical response
    `+13,+1.29383828200000E-006,+1.29352315400000E-006,...`); User's Guide, "Time stamp
    measurements" (p. 88-89 in the Agilent edition, p. 100-101 in Keysight's): "count+1
    elements are actually returned", and each value is "the signal period itself (scale
    factor = 1 ...) or the signal period multiplied by the scale factor". So value k is
    the interval from stamp k-1 to stamp k; we take stamp 0 as the start event (the
    trigger), which is how the time tie places the first zero mark (unverified on a real
    53230A: the manual's examples run on a free-running input).
    A prescaler k > 1 means only every k-th edge was stamped (the counter does that for
    inputs faster than the timestamp rate); a once-per-rev signal must give 1.
    """

    name = "keysight-tst"

    def encode(self, edges_s: np.ndarray, t_start_s: float, digits: int,
               exp_digits: int, first_index: int = 0) -> str:
        import numpy as np
        intervals = np.diff(np.concatenate([[t_start_s], np.asarray(edges_s, float)]))
        return ",".join(["+1"] + [nr3(t, digits, exp_digits) for t in intervals])

    def decode(self, values: np.ndarray) -> np.ndarray:
        import numpy as np
        if values.size < 2:
            raise ValueError("expected the prescaler and at least one interval")
        if values[0] != 1:
            raise ValueError(f"prescaler {values[0]:g}: the counter stamped only every "
                             f"{values[0]:g}-th edge (input too fast for SENS:TST:RATE)")
        intervals = values[1:]
        finite = intervals[intervals < 0.999 * SCPI_NAN]
        if np.any(finite <= 0):
            bad = int(np.argmax(finite <= 0))
            raise ValueError(f"interval {bad + 1} is {finite[bad]:g} s: the 53230A's "
                             "values are intervals between stamps and must be positive")
        return np.cumsum(intervals)

    def n_values(self, n_edges: int) -> int:
        return n_edges + 1


# -- the 53230A's first timestamp value: two readings of the manual ------------------------
#
# The Programmer's Reference (SENSe:TSTamp:RATE, typical response
# `+13,+1.29383828200000E-006,+1.29352315400000E-006,...`) shows, on a free-running
# input, a first value equal to a full period: stamp 0 is then the first EDGE, not the
# trigger, and the reply says nothing about when that edge came after the trigger. The
# twin long assumed the other reading (value 1 = trigger to first edge). No public
# client program we read (opronningen/53230A-Toolkit, joewhalen/keysight_53230A,
# francescobenfenati/Agilent-53230A-remote-control) uses the first value at all.
# So the tie must not rest on either reading: `first_interval_is_a_turn` tells them apart
# on the data (a trigger falls anywhere in a turn, an edge-to-edge value is one turn like
# the others), and the driver refuses edges whose first value is a full turn.

FIRST_VALUE_READINGS = ("from-start", "edge-to-edge")
#: the manual's example (SENSe:TSTamp:RATE): stamp 0 is an edge
MANUAL_FIRST_VALUE = "edge-to-edge"


def first_interval_is_a_turn(intervals_s: np.ndarray, expected_period_s: float,
                             resolution_s: float) -> bool:
    """True when the first interval is as long as the full turns after it (within their
    own scatter, 10 sigma, never tighter than 20 resolution steps), or, with fewer than
    three turns to compare, within 1e-3 of the expected period.

    A trigger-to-first-edge value is uniform over a turn: it looks like a turn by chance
    with probability about (window / turn), 1e-7 at the stand's jitter."""
    import numpy as np
    v = np.asarray(intervals_s, float)
    v = v[v < 0.999 * SCPI_NAN]
    if v.size < 1:
        return False
    turns = v[1:]
    if turns.size >= 3:
        window = max(10.0 * float(np.std(turns, ddof=1)), 20.0 * resolution_s)
        return abs(float(v[0]) - float(np.median(turns))) <= window
    return abs(float(v[0]) - expected_period_s) <= 1e-3 * expected_period_s


def first_value_is_a_turn(intervals_s: np.ndarray, expected_period_s: float,
                          resolution_s: float, seen_from_start: bool) -> bool:
    """`first_interval_is_a_turn`, with what this counter has already shown.

    A counter that stamps edge to edge gives a first value as long as a turn every time;
    one first value clearly shorter than a turn therefore proves the counter stamps from
    its trigger (`seen_from_start`), and that is firmware behaviour, not chance. With
    three or more turns the turns' own scatter decides (a contradiction is refused by the
    caller); with fewer, a first value near a turn is only the trigger falling just after
    a zero mark (the slow rates of the paper's ladder, armed right after the reversal
    carried the table over the mark: 3598.2 s against a 3600 s turn), and it is read as
    trigger to first edge when the counter has shown that reading before."""
    import numpy as np
    full = first_interval_is_a_turn(intervals_s, expected_period_s, resolution_s)
    v = np.asarray(intervals_s, float)
    few_turns = int(np.count_nonzero(v[1:] < 0.999 * SCPI_NAN)) < 3
    return full and not (few_turns and seen_from_start)


class PendulumStst(TimestampFormat):
    """CNT-91 `CONF:ARR:STST` with `FORM:TINF ON`: pairs (X, TS) per stamp.

    CNT-90 series Programmer's Handbook, :MEASure:ARRay:STSTamp? (p. 8-72): "The X
    counter records the number of trigger level crossings"; TS is "seconds since a certain
    start event that is not available for external control", so only differences of TS
    mean anything. The handbook does not say X steps by one per stamp; it says stamps
    have a dead time (down to 4 us) in which crossings are counted but not stamped. So
    the rule here: every stamp must follow the previous one by the same number of
    crossings as the first pair does; a larger step is a crossing that was counted but
    not stamped (a missed zero mark), and the data are refused rather than returned as a
    two-turn period.
    """

    name = "pendulum-stst"

    def encode(self, edges_s: np.ndarray, t_start_s: float, digits: int, exp_digits: int,
               first_index: int = 0) -> str:
        return ",".join(f"{first_index + i + 1},{nr3(t - t_start_s, digits, exp_digits)}"
                        for i, t in enumerate(edges_s))

    def decode(self, values: np.ndarray) -> np.ndarray:
        import numpy as np
        if values.size < 2 or values.size % 2:
            raise ValueError(f"expected (X, TS) pairs, got {values.size} values")
        x, ts = values[0::2], values[1::2]
        steps = np.diff(x)
        if steps.size and (steps[0] < 1 or np.any(steps != steps[0])):
            bad = int(np.argmax(steps != steps[0])) if steps[0] >= 1 else 0
            raise ValueError(f"the crossing count X steps by {steps[bad]:g} after "
                             f"timestamp {bad + 1} (by {steps[0]:g} before): crossings "
                             "were counted but not stamped, edges were missed")
        return ts

    def n_values(self, n_edges: int) -> int:
        return 2 * n_edges


TIMESTAMP_FORMATS: dict[str, TimestampFormat] = {
    f.name: f for f in (KeysightTimestamps(), PendulumStst())}


def encode_values(values: np.ndarray, digits: int = 15, exp_digits: int = 2) -> str:
    """A plain list of readings (periods): `+3.6E-01,+3.6E-01`."""
    import numpy as np
    return ",".join(nr3(v, digits, exp_digits) for v in np.atleast_1d(values))


def is_scpi_nan(values: np.ndarray) -> np.ndarray:
    """Readings that are SCPI's 9.91E37 (a measurement that timed out)."""
    import numpy as np
    return np.asarray(values) >= 0.999 * SCPI_NAN


# -- what users' own 53230A scripts send (the twin serves these; the driver needs none) ------

@dataclass(frozen=True)
class Keysight53230aScriptWords:
    """Words of the 53220A/53230A Programmer's Reference that public client programs
    send (opronningen/53230A-Toolkit: R/R.cs `:DATA:REMOVE? n,WAIT`, Ag53230A.cs
    `Abort;*WAI;*LRN?`, `FORM ASC,15` / `REAL,64`, `FORM:BORD`; 53230A_Model.cs the
    `:TRIG:COUN`, `:TRIG:DEL`, `:TRIG:SLOP`, `:FREQ:MODE` settings; joewhalen/
    keysight_53230A counter.py `TRIG:SOUR IMM; COUN MAX`, `SENS:FREQ:MODE REC`, `R?`;
    francescobenfenati/Agilent-53230A-remote-control `READ?`; TimingKeepers/
    measuring_instr driver/ks53230.py `CONF:PER DEF,DEF,(@1)`, `TRIGger:...`). Parameter
    lists are parsed by the twin itself (raw routes). Issue 41, from the reference's own
    command pages (page numbers not at hand): TRIGger:SOURce BUS with IEEE 488.2 *TRG;
    FORMat[:DATA] REAL (FETC?/READ? `#0` block); CONFigure:TINTerval [(@1),(@2)],
    CONFigure:TOTalize:TIMed [<gate>,][(@ch)], CONFigure:TSTamp [{<count>}][,(@ch)]
    (example `CONF:TST (5000)`); SAMPle:COUNt and TRIGger:COUNt 1 to 1,000,000 with
    MIN/MAX/DEF queries."""

    read_remove: Command = Command("R?", doc="[<max>]: readings removed, definite-length block")
    data_remove: Command = Command("DATA:REMove?", doc="<n>[,WAIT]: n readings removed")
    data_points: Command = Command("DATA:POINts?", doc="readings in memory")
    measure_timestamps: Command = Command("MEASure:ARRay:TSTamp?", doc="(<n>),(@<ch>)")
    measure_period: Command = Command("MEASure:PERiod?", doc="[<exp>,<res>,](@<ch>)")
    measure_frequency: Command = Command("MEASure[:SCALar]:FREQuency?",
                                         doc="[<exp>,<res>,](@<ch>)")
    configure_period: Command = Command("CONFigure:PERiod", doc="[<exp>,<res>,](@<ch>)")
    configure_frequency: Command = Command("CONFigure[:SCALar]:FREQuency",
                                           doc="[<exp>,<res>,](@<ch>)")
    configure_timestamp: Command = Command("CONFigure:TSTamp", doc="[(@<ch>)]")
    configure_query: Command = Command("CONFigure?", doc="the function and its channel")
    learn: Command = Command("*LRN?", doc="the settings as commands that restore them")
    status_byte: Command = Command("*STB?", doc="status byte")
    scpi_version: Command = Command("SYSTem:VERSion?", doc="SCPI version: 1994.0")
    trigger_count: Command = Command("TRIGger[:SEQuence]:COUNt", doc="1..1e6, MIN, MAX, DEF")
    trigger_delay: Command = Command("TRIGger[:SEQuence]:DELay", doc="0..3600 s")
    trigger_slope: Command = Command("TRIGger[:SEQuence]:SLOPe", doc="POSitive, NEGative")
    byte_order: Command = Command("FORMat:BORDer", doc="NORMal, SWAPped")
    frequency_mode: Command = Command("[SENSe:]FREQuency:MODE",
                                      doc="AUTO, CONTinuous, RCONtinuous, RECiprocal")
    format_data: Command = Command("FORMat[:DATA]", doc="ASCii[,<1..15>] or REAL[,64]")
    sample_count: Command = Command("SAMPle:COUNt", doc="1..1e6, MIN, MAX, DEF; the query "
                                    "takes MIN, MAX or DEF too (SAMPle:COUNt page)")
    configure_time_interval: Command = Command(
        "CONFigure:TINTerval", doc="[(@1),(@2)]: start on one channel, stop on the other")
    configure_totalize_timed: Command = Command(
        "CONFigure:TOTalize:TIMed", doc="[<gate>,][(@<ch>)]: edges counted in a gate")


KEYSIGHT_53230A_SCRIPT_WORDS = Keysight53230aScriptWords()
#: the 53230A's TRIGger:COUNt and SAMPle:COUNt upper limit (Programmer's Reference,
#: TRIGger:COUNt and SAMPle:COUNt: 1 to 1,000,000)
KEYSIGHT_53230A_COUNT_MAX = 1_000_000


@dataclass(frozen=True)
class Cnt91ScriptWords:
    """Words PyMeasure's CNT91 driver (pymeasure.instruments.pendulum.cnt91) sends,
    as the CNT-90 series Programmer's Handbook names them: FORMat:SMAX p. 8-39,
    :ACQuisition:APERture p. 8-92 (2e-8..1000 s), :CONFigure:ARRay:FREQuency[:BTB],
    ARM:SOURce/SLOPe/COUNt, INITiate:CONTinuous, :CALibration:INTerpolator:AUTO."""

    format_smax: Command = Command("FORMat:SMAX?", doc="most results one FETC:ARR? gives")
    continuous: Command = Command("INITiate:CONTinuous", doc="ON/OFF or 1/0")
    aperture: Command = Command("ACQuisition:APERture", doc="gate time, 2e-8..1000 s")
    arm_source: Command = Command("ARM[:STARt][:LAYer2]:SOURce",
                                  doc="IMMediate, EXTernal1, EXTernal2, EXTernal4")
    arm_slope: Command = Command("ARM[:STARt][:LAYer2]:SLOPe", doc="POSitive, NEGative")
    arm_count: Command = Command("ARM[:STARt][:LAYer1]:COUNt", doc="1..2e9, INF")
    interpolator_auto: Command = Command("CALibration:INTerpolator:AUTO", doc="ON/OFF")
    configure_frequency_array: Command = Command("CONFigure:ARRay:FREQuency",
                                                 doc="<n>,(@<ch>): n frequencies")
    configure_frequency_array_btb: Command = Command("CONFigure:ARRay:FREQuency:BTB",
                                                     doc="<n>,(@<ch>): back to back")
    configure_frequency: Command = Command("CONFigure[:SCALar]:FREQuency", doc="[(@<ch>)]")
    configure_period: Command = Command("CONFigure[:SCALar]:PERiod", doc="[(@<ch>)]")
    measure_frequency: Command = Command("MEASure[:SCALar]:FREQuency?", doc="[(@<ch>)]")
    measure_period: Command = Command("MEASure[:SCALar]:PERiod?", doc="[(@<ch>)]")
    read: Command = Command("READ?", doc="INIT and FETCh? in one")
    fetch: Command = Command("FETCh?", doc="the last result")
    status_byte: Command = Command("*STB?")
    options: Command = Command("*OPT?")
    # time stamps as scripts ask for them (CNT-90 series Programmer's Handbook,
    # :MEASure:ARRay:STSTamp? p. 8-72 and its sibling :MEASure:ARRay:TSTAmp?)
    measure_single_timestamps: Command = Command("MEASure:ARRay:STSTamp?",
                                                 doc="(<n>)[,(@<ch>)]")
    measure_timestamps: Command = Command("MEASure:ARRay:TSTAmp?", doc="(<n>)[,(@<ch>)]")
    configure_timestamps: Command = Command("CONFigure:ARRay:TSTAmp", doc="(<n>)[,(@<ch>)]")


CNT91_SCRIPT_WORDS = Cnt91ScriptWords()
#: reading memory (Programmer's Reference, DATA:POINts?: 1,000,000 readings)
KEYSIGHT_53230A_MEMORY = 1_000_000


# -- the profile ----------------------------------------------------------------------------

@dataclass(frozen=True)
class CounterProfile:
    """One counter model: words, capabilities, reply formats and metrology."""

    model: str
    maker: str
    description: str
    words: CounterWords
    #: regex searched (case-insensitive) in the *IDN? reply; None accepts any instrument
    idn_pattern: str | None
    #: timestamp reply format (a TIMESTAMP_FORMATS key); None: no timestamps
    timestamps: str | None
    #: how N periods are measured: 'init-fetch' (SAMP:COUN N; INIT; FETC?), 'read'
    #: (one READ? per period), or None (periods only as differences of timestamps)
    periods: str | None
    #: period-mode readings are consecutive turns (no dead time between them)
    periods_gap_free: bool = False
    channels: tuple[int, ...] = (1, 2)
    impedances_ohm: tuple[float, ...] = (50.0, 1.0e6)
    couplings: tuple[str, ...] = ("AC", "DC")
    slopes: tuple[str, ...] = ("POS", "NEG")
    level_range_v: tuple[float, float] = (-5.0, 5.0)
    max_count: int = 1_000_000
    #: the instrument's own measurement timeout (`measurement_timeout` word), s, or None
    measurement_timeout_range_s: tuple[float, float] | None = None
    #: value sent to `timestamp_rate` (Hz), if the model has that word
    timestamp_rate_hz: float | None = None
    #: most results one FETC:ARR? may ask for (None: the model fetches all at once)
    fetch_max_results: int | None = None
    #: the `trigger_source` value that starts a measurement from the external input the
    #: FOG's sync pulse is wired to (53230A: EXT, the rear Trig In; CNT-91: EXT4, the
    #: rear arming input E of ARM:SOURce)
    external_trigger: str = "EXT"
    #: where the words, limits and reply formats were checked: manual and section, or
    #: "unverified" when no manual was found
    manual: str = "unverified"
    #: metrology (docs/method.md A1, d_counter)
    resolution_s: float = 1e-9
    single_shot_s: float = 1e-9
    timebase_limit_rel: float = 1e-6
    notes: str = ""
    #: what the twin prints: significant digits after the point, exponent digits
    reply_digits: int = 15
    reply_exp_digits: int = 2
    #: the identity a twin of this model answers with (a real instrument has its own)
    idn: str = field(default="", compare=False)

    @property
    def supports_timestamps(self) -> bool:
        """Edge timestamps: what the rate ladder needs (N+1 consecutive zero marks)."""
        return self.timestamps is not None

    @property
    def has_reference_source(self) -> bool:
        """A word that selects the timebase (stand key counter.reference)."""
        return self.words.reference_source is not None

    @property
    def has_reference_check(self) -> bool:
        """A word that checks the external reference signal (else only the selection's
        own error, if the model gives one, tells that nothing is wired)."""
        return self.words.reference_check is not None

    @property
    def has_external_trigger(self) -> bool:
        """A word that starts a measurement from an external input: what a fog-sync time
        tie needs (stand key counter.time_tie.source: fog-sync)."""
        return self.words.trigger_source is not None

    @property
    def has_measurement_timeout(self) -> bool:
        """The instrument's own measurement timeout (9.91E37 for a silent input)."""
        return (self.words.measurement_timeout is not None
                and self.measurement_timeout_range_s is not None)

    def missing_capabilities(self, *, timestamps: bool = False, reference: str | None = None,
                             time_tie: str | None = None) -> list[tuple[str, str]]:
        """What a stand or procedure asks of this model that it cannot do, as (stand key,
        sentence) pairs, for validation before anything is opened: `timestamps` (the rate
        ladder), `reference` (counter.reference), `time_tie` (counter.time_tie.source)."""
        out = []
        if timestamps and not self.supports_timestamps:
            out.append(("model", f"the {self.model} cannot timestamp edges "
                                 "(supports_timestamps): the rate ladder needs N+1 "
                                 "consecutive zero-mark timestamps"))
        if reference is not None and not self.has_reference_source:
            out.append(("reference", f"the {self.model} profile has no reference-source "
                                     "word (has_reference_source): remove "
                                     "counter.reference or choose another model"))
        if time_tie == "fog-sync" and not self.has_external_trigger:
            out.append(("time_tie", f"the {self.model} profile has no trigger-source word "
                                    "(has_external_trigger): a fog-sync time tie needs "
                                    "an external start; use host-clock"))
        return out

    @property
    def timestamp_format(self) -> TimestampFormat:
        if self.timestamps is None:
            raise ValueError(f"{self.model} has no timestamp mode")
        return TIMESTAMP_FORMATS[self.timestamps]

    @property
    def timebase_u_rel(self) -> float:
        """Standard uncertainty of the timebase, from its +/- limit (rectangular)."""
        return self.timebase_limit_rel / math.sqrt(3.0)

    def period_u_s(self, period_s: float) -> float:
        """Standard uncertainty (k=1) of one period from the counter alone, s.

        docs/method.md A1 (d_counter): two independent timestamps, each with the single-shot
        error, plus the timebase's fractional error times the period. The trigger error
        (d_trigger) is the sensor's and the stand file's, not the counter's.
        """
        return math.hypot(math.sqrt(2.0) * self.single_shot_s, self.timebase_u_rel * period_s)

    def quantise(self, t_s: np.ndarray) -> np.ndarray:
        """Times as this counter reports them: rounded to its resolution."""
        import numpy as np
        return np.round(np.asarray(t_s, dtype=float) / self.resolution_s) * self.resolution_s


KEYSIGHT_53230A = CounterProfile(
    model="keysight-53230a",
    maker="Keysight (Agilent)",
    description="53230A 350 MHz universal counter: timestamps (CONF:ARR:TST) and periods",
    idn_pattern=r"53230A",
    words=CounterWords(
        input_level_auto=Command("INPut{channel}:LEVel[1]:AUTO", "{state}"),
        input_level=Command("INPut{channel}:LEVel[1][:ABSolute]", "{level_v}"),
        configure_timestamps=Command("CONFigure:ARRay:TSTamp", "({count}),(@{channel})",
                                     doc="N timestamps of one channel's edges"),
        configure_period=Command("CONFigure:PERiod", "(@{channel})", doc="period mode"),
        timestamp_rate=Command("[SENSe:]TSTamp:RATE", "{rate_hz}",
                               doc="nominal timestamp rate: 10E3, 100E3, 800E3 or 1E6"),
        sample_count=Command("SAMPle:COUNt", "{count}", doc="readings per trigger"),
        gate_time=Command("[SENSe:]FREQuency:GATE:TIME", "{gate_s}",
                          doc="shortest gate: one period per reading"),
        measurement_timeout=Command("SYSTem:TIMeout", "{timeout_s}",
                                    doc="per-reading timeout (not per acquisition), kept "
                                        "in non-volatile memory: read, set, restored"),
        trigger_source=Command("TRIGger[:SEQuence]:SOURce", "{source}",
                               doc="IMMediate, EXTernal or BUS; EXT for the time tie"),
        reference_source=Command("[SENSe:]ROSCillator:SOURce", "{source}",
                                 doc="INTernal or EXTernal timebase (EXT also ends AUTO)"),
        reference_check=Command("[SENSe:]ROSCillator:EXTernal:CHECk", "{when}",
                                doc="ONCE: checks the Ext Ref In signal, errors if none"),
        fetch=Command("FETCh?", doc="readings of the last INIT"),
        read=Command("READ?", doc="ABORt, INIT, FETCh? in one"),
    ),
    timestamps="keysight-tst",
    periods="init-fetch",
    periods_gap_free=False,
    channels=(1, 2),
    level_range_v=(-5.0, 5.0),
    max_count=1_000_000,
    measurement_timeout_range_s=(0.01, 2000.0),
    timestamp_rate_hz=1.0e4,
    resolution_s=20e-12,
    single_shot_s=20e-12,
    timebase_limit_rel=1.0e-6,
    manual=("Keysight 53220A/53230A Programmer's Reference: MEASure:ARRay:TSTamp? p. 240, "
            "SENSe:TSTamp:RATE p. 377 (*RST 1.0E6), SYSTem:TIMeout p. 459 (per measurement, "
            "non-volatile, 9.9E37 disabled); User's Guide 'Time stamp' (count+1 elements, "
            "values are period x scale factor) and 'Time base' (SENS:ROSC:SOUR EXT; "
            "SENS:ROSC:EXT:CHEC ONCE; SYST:ERR?, p. 69/81)"),
    notes=("53220A/53230A Programmer's Reference: CONF:ARR:TST, SENS:TST:RATE, SYST:TIM, "
           "INP:LEV:AUTO, reply 'prescaler, intervals' (count+1 values). Period mode "
           "(CONF:PER; SAMP:COUN N) is modelled with dead time: consecutive readings time "
           "every other turn; use timestamps for consecutive turns. Timebase: standard "
           "TCXO, +/-1e-6 assumed (1-year aging and temperature); option 010 OCXO is far "
           "better: take the calibration certificate's figure."),
    reply_digits=14,   # 15 significant: `+1.29383828200000E-006` (SENSe:TSTamp:RATE)
    reply_exp_digits=3,
    idn="Keysight Technologies,53230A,MY00000000,03.02-1519.2432-3.15-4.16-127-155-35",
)

#: the 53230A's sibling: the same SCPI words, but no time stamps ("Time stamp measurements
#: are available with the 53230A only", 53220A/53230A User's Guide, "Time stamp", p. 99
#: Keysight edition / p. 87 Agilent edition) and 100 ps single-shot (datasheet). The rate
#: ladder needs time stamps, so `bench validate` refuses it for the ladder, by name.
KEYSIGHT_53220A = dataclasses.replace(
    KEYSIGHT_53230A,
    model="keysight-53220a",
    description="53220A 350 MHz universal counter: periods only (no time stamps)",
    idn_pattern=r"53220A",
    words=dataclasses.replace(KEYSIGHT_53230A.words, configure_timestamps=None,
                              timestamp_rate=None),
    timestamps=None,
    timestamp_rate_hz=None,
    resolution_s=100e-12,
    single_shot_s=100e-12,
    manual=("Keysight 53220A/53230A Programmer's Reference (the 53230A's words, less "
            "CONF:ARR:TST and SENS:TST:RATE); User's Guide 'Time stamp' (p. 99: time stamps "
            "on the 53230A only)"),
    notes=("The 53230A profile without time stamps: periods by CONF:PER; SAMP:COUN N; "
           "INIT; FETC? (with dead time between readings). 100 ps single-shot time interval "
           "resolution per the 53220A/53230A datasheet; timebase as the 53230A's standard "
           "TCXO until the calibration certificate's figure is entered."),
    idn="Keysight Technologies,53220A,MY00000000,03.02-1519.2432-3.15-4.16-127-155-35",
)

PENDULUM_CNT91 = CounterProfile(
    model="pendulum-cnt-91",
    maker="Pendulum Instruments",
    description="CNT-91 timer/counter/analyzer: single timestamps (CONF:ARR:STST)",
    idn_pattern=r"CNT-9[01]",
    words=CounterWords(
        input_level=Command("INPut{channel}:LEVel", "{level_v}"),
        configure_timestamps=Command("CONFigure:ARRay:STSTamp", "({count}),(@{channel})",
                                     doc="N single time stamps of trigger-level crossings"),
        timestamp_info=Command("FORMat:TINFormation", "{state}",
                               doc="ON: each result is (X count, timestamp)"),
        fetch_array=Command("FETCh:ARRay?", "{count}",
                            doc="the next <count> results (at most 10 000 a call)"),
        # start arming (PyMeasure's cnt91: external_start_arming_source, A/B/E = EXT1/
        # EXT2/EXT4): the FOG's sync pulse on the rear arming input E starts the stamps
        trigger_source=Command("ARM[:STARt][:LAYer2]:SOURce", "{source}",
                               doc="IMMediate or EXTernal4 (rear arming input E): what "
                                   "starts the measurement; EXT4 for the time tie"),
        reference_source=Command("[SENSe:]ROSCillator:SOURce", "{source}",
                                 doc="INTernal, EXTernal or AUTO timebase (syntax "
                                     "unverified, see notes)"),
    ),
    timestamps="pendulum-stst",
    periods=None,
    channels=(1, 2),
    level_range_v=(-5.0, 5.0),
    max_count=1_000_000,
    fetch_max_results=10_000,
    external_trigger="EXT4",
    manual=("Pendulum CNT-90 series Programmer's Handbook: :FETCh:ARRay? p. 8-35 (the next "
            "<size> results, 'maximum limit is 10000'), :FORMat:SMAX p. 8-39, "
            ":MEASure:ARRay:STSTamp? p. 8-72 (X counter = trigger-level crossings; TS since "
            "an unknown start event), :ACQuisition:APERture p. 8-92, :FORMat[:DATA] "
            "{ASCii|REAL} (REAL: IEEE 754 8-byte big-endian, definite-length block); "
            ":ARM:SOURce as "
            "PyMeasure's cnt91 sends it. Unverified: the largest STST array size, "
            ":SENSe:ROSCillator:SOURce"),
    resolution_s=50e-12,
    single_shot_s=50e-12,
    timebase_limit_rel=2.0e-6,
    notes=("CNT-90/91 Programmer's Handbook: :MEAS/:CONF:ARR:STST (<size>),(@1) gives "
           "X,TS pairs (FORM:TINF ON), dead time between stamps down to 4 us. Unsure: "
           "whether FETC:ARR? blocks until all stamps exist (we poll *ESR? for OPC before "
           "it, which does not depend on that). No measurement-timeout word is used: the "
           "VISA timeout, scaled to the expected period, bounds the wait. Timebase: "
           "standard crystal, +/-2e-6 assumed; options 19/30/40 (OCXO) and CNT-91R "
           "(rubidium) far better. UNVERIFIED, no handbook page at hand: the timebase word "
           "[:SENSe]:ROSCillator:SOURce {INTernal|EXTernal|AUTO} (the twin answers exactly "
           "this, INT/EXT/AUTO; with EXTernal selected and no valid signal at the "
           "reference input it queues -241 'Hardware missing', our assumption: the "
           "handbook has no check word like the 53230A's ROSC:EXT:CHEC); the time tie "
           "takes TS as counted from the measurement's start (INIT, or with ARM:SOUR EXT4 "
           "the first arming pulse after it), which p. 8-72 ('a certain start event that "
           "is not available for external control') does not promise, so the driver "
           "refuses edges whose first TS is longer than a turn (TS from another origin); "
           "the reply layout of :MEAS:ARR:TSTAmp? (TS values; X,TS pairs with FORM:TINF "
           "ON) is modelled on STSTamp's."),
    idn="Pendulum Instruments AB,CNT-91,608500,V1.28 26 Jan 2011 08:57",
)

GENERIC_SCPI_PERIOD = CounterProfile(
    model="generic-scpi-period",
    maker="any",
    description="a SCPI period counter (CONF:PER; READ?), e.g. the AKIP-5102 of the paper",
    idn_pattern=None,
    words=CounterWords(
        input_level_auto=Command("[SENSe:]EVENt{channel}:LEVel[:ABSolute]:AUTO", "{state}"),
        input_level=Command("[SENSe:]EVENt{channel}:LEVel[:ABSolute]", "{level_v}"),
        input_slope=Command("[SENSe:]EVENt{channel}:SLOPe", "{slope}"),
        configure_period=Command("CONFigure:PERiod", "(@{channel})"),
        read=Command("READ?", doc="measure one period now and return it"),
        format_data=None,
    ),
    timestamps=None,
    periods="read",
    periods_gap_free=False,
    channels=(1, 2),
    level_range_v=(-5.0, 5.0),
    max_count=1,
    resolution_s=1e-9,
    single_shot_s=1e-9,
    timebase_limit_rel=5.0e-6,
    manual="unverified: no AKIP-5102 manual found; SCPI-99 words as the HP 53131A's",
    notes=("SCPI-99 words as the HP 53131A uses them (trigger level and slope in "
           "SENSe:EVENt, coupling and impedance in INPut), which most SCPI period "
           "counters copy; the AKIP-5102's own manual was not available to us, so check "
           "its words on the first connection (a wrong one is reported as -113 by name). "
           "Each READ? times the first whole turn after it arrives: N periods are N "
           "separate turns, not consecutive ones. Metrology placeholders: the paper puts "
           "the AKIP-5102/1's period error an order below 0.1 us; 1 ns single-shot and "
           "+/-5e-6 timebase are assumed until the certificate's figures are entered."),
    idn="AKIP,AKIP-5102/1,000000001,1.00",
)

PROFILES: dict[str, CounterProfile] = {
    p.model: p for p in (KEYSIGHT_53230A, KEYSIGHT_53220A, PENDULUM_CNT91,
                         GENERIC_SCPI_PERIOD)}


def get_profile(model: str) -> CounterProfile:
    """The profile of a model name as stand files spell it (`keysight-53230a`)."""
    try:
        return PROFILES[model.strip().lower()]
    except KeyError:
        raise KeyError(f"unknown counter model {model!r}; known: "
                       f"{', '.join(sorted(PROFILES))}") from None
