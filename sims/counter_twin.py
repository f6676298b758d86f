"""The frequency counter's twin: times the simulated stand's zero mark over real SCPI.

It speaks the words of one counter profile (drivers/counter_profiles.py, imported, not
copied) on a TCP socket (sims/scpi_server.py) and answers from the stand's truth: on INIT
(or READ?) it notes the stand clock's now() as the arm time; the readings are the next
zero-mark edges after it (`AxisModel.zero_marks(...).t_edge_s`, which carry the slot
sensor's jitter), on the stand's time axis, rounded to the profile's resolution (20 ps
for the 53230A). It waits in real time until the virtual clock has passed the last edge
it reports, so a driver sees the same timing a real counter would give it, sped up.

Measurement modes, as the manuals describe them:
- timestamps: n consecutive edges after the start event (53230A: `+1,d1,..,dn`, the
  prescaler and then the interval from each stamp to the next, stamp 0 being the start
  event, Programmer's Reference p. 240/377 and User's Guide "Time stamp"; CNT-91:
  `1,ts1,2,ts2,..`, TS since the start event, Programmer's Handbook p. 8-72). The start
  event is INIT with TRIG:SOUR IMM (the *RST value) or, with TRIG:SOUR EXT, the first
  pulse of the FOG's sync output after INIT as it reaches the counter through the
  `SyncLink` (its latency and jitter: the physical time tie, drivers/time_tie.py);
- period readings (53230A CONF:PER with SAMP:COUN n): each reading times one turn from
  the first edge after the previous reading ended, so readings are every other turn;
- READ? (generic counter): one period, from the first edge after the READ? arrived;
- totalize, timed (53230A CONF:TOT:TIM): the zero marks counted in each gate, gates back
  to back from the start event. CONF:TINT configures (CONF? reports it) but measuring a
  time interval is not modelled: INIT and READ? are -221 "Settings conflict;..." rather
  than a wrong number.

The start event: INIT with TRIG:SOUR IMM; with TRIG:SOUR EXT (53230A) or ARM:SOUR EXT4
(CNT-91 start arming on the rear input E) the FOG's sync pulse, through the `SyncLink`;
with TRIG:SOUR BUS (53230A) INIT waits for *TRG (IEEE 488.2 10.37), each *TRG starting
SAMP:COUN readings of TRIG:COUN, from the later of the trigger and the end of the last
trigger's readings; *TRG with nothing waiting is -211, READ? with BUS -214 "Trigger
deadlock". CNT-91 arming on input A or B (EXT1, EXT2) is not modelled (-221 at INIT).

FORMat REAL: the 53230A answers FETC? and READ? with an indefinite-length block, `#0`,
the doubles (FORM:BORD order), then the terminator (Programmer's Reference, FORMat:DATA),
R? and DATA:REM? with a definite-length block; the CNT-91 answers big-endian doubles in a
definite-length block (CNT-90 series Programmer's Handbook, :FORMat).

The timebase: the 53230A's SENS:ROSC:SOUR INT|EXT, with SENS:ROSC:EXT:CHEC ONCE an error
(-241) when `external_reference` is False; the CNT-91's ROSC:SOUR INT|EXT|AUTO (syntax
unverified, see its profile's notes), EXT itself the error (-241) when nothing is wired.

SYSTem:TIMeout is per reading and non-volatile (Programmer's Reference p. 459): *RST
leaves it, and it starts disabled (as shipped) unless the twin is built with another.
FETC:ARR? returns the next results each call, at most `fetch_max_results` (CNT-91:
10 000, Programmer's Handbook p. 8-35); more is -222.

The input is modelled just enough to make a wrong set-up fail as on a bench: the zero
mark is wired to `signal_channel` and swings `signal_low_v .. signal_high_v`; a level
outside that swing, another channel, or auto-level left ON (it cannot settle on a
once-per-revolution pulse) sees no edges. With no edges, a model with a measurement
timeout (53230A SYST:TIM, counted per reading, in virtual seconds) answers 9.91E37 for
the missing readings; one without it never answers, as a real counter would not.
The slope and coupling are stored but do not move the edges (the stand has one edge
per mark).

Faults (`inject`): 'no-trigger' (the next measurement sees no edges), and the base's
'garbage' and 'drop' on the next data query (FETC?, FETC:ARR?, READ?).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from drivers.counter_profiles import (
    CNT91_SCRIPT_WORDS,
    FIRST_VALUE_READINGS,
    KEYSIGHT_53230A_COUNT_MAX,
    KEYSIGHT_53230A_MEMORY,
    KEYSIGHT_53230A_SCRIPT_WORDS,
    TIMESTAMP_FORMATS,
    CounterProfile,
    encode_values,
    get_profile,
)
from drivers.counter_profiles import nr3 as profile_nr3
from drivers.scpi import SCPI_NAN, TRG, count_params, parse_numbers
from sims.scpi_server import (
    ExecError,
    ScpiServer,
    bool_param,
    bool_reply,
    count_param,
    enum_param,
    nr3,
    number_param,
    ranged_param,
    suffix_item,
)
from sims.stand import SimulatedStand


@dataclass
class InputState:
    """One input channel's settings as the twin holds them (*RST values)."""

    coupling: str = "AC"
    impedance_ohm: float = 1.0e6
    level_auto: bool = True
    level_v: float = 0.0
    slope: str = "POS"


@dataclass(frozen=True)
class SyncLink:
    """The FOG's sync output wired to the counter's external trigger: a pulse at FOG time
    k * period_s (every n-th sample), reaching the counter `latency_s` later with a
    Gaussian `jitter_s` (std) of its own."""

    period_s: float
    latency_s: float = 0.0
    jitter_s: float = 0.0

    def next_pulse_s(self, t_s: float, rng: np.random.Generator) -> float:
        """When the first sync pulse after stand time t_s reaches the counter."""
        k = math.floor(t_s / self.period_s) + 1
        return k * self.period_s + self.latency_s + self.jitter_s * float(rng.standard_normal())


Kind = Literal["timestamps", "periods", "totals"]


@dataclass
class TwinAcquisition:
    """A measurement in progress (or done) on the twin."""

    kind: Kind
    n: int                      # readings
    channel: int
    t_arm_s: float              # stand time of INIT / READ?
    timeout_s: float | None     # the instrument's own per-reading timeout, virtual s
    blind: bool                 # no edges reach the counter (set-up or 'no-trigger')
    t_start_s: float = 0.0      # the start event: INIT, or the sync pulse (TRIG:SOUR EXT)
    values: np.ndarray | None = None
    edges_s: np.ndarray = field(default_factory=lambda: np.empty(0))
    fetched: int = 0            # results already sent by FETC:ARR?
    removed: int = 0            # reading-memory items removed by R? / DATA:REM?
    #: stamp 0: the start event, or (first_value "edge-to-edge") the first edge after it
    edge_to_edge: bool = False
    stamp0_s: float | None = None
    #: frequency readings (CONF:FREQ, MEAS:FREQ?): 1 / period
    invert: bool = False
    #: gated readings (CNT-91 ACQ:APER): each spans whole turns until the gate time has
    #: passed; back to back, the next starts where it ended (no dead time)
    walk: bool = False
    gate_s: float = 0.0
    back_to_back: bool = False
    #: TRIG:SOUR BUS (53230A): each of `blocks` triggers (*TRG) starts `n / blocks`
    #: readings; `triggers` holds their stand times, the first is the start event
    bus: bool = False
    blocks: int = 1
    triggers: list[float] = field(default_factory=list)
    #: every trigger received so far has been served: the next reading waits for *TRG
    waiting_trigger: bool = False

    @property
    def edges_needed(self) -> int:
        if self.kind == "timestamps":
            return self.n + (1 if self.edge_to_edge else 0)
        if self.kind == "totals":
            return 0
        return 2 * self.n

    @property
    def edges_per_reading(self) -> int:
        return 1 if self.kind == "timestamps" else 2


class CounterTwin(ScpiServer):
    """A counter of `model` watching the zero mark of `stand.axes[axis]`."""

    fault_names = ScpiServer.fault_names | {"no-trigger"}

    def __init__(self, stand: SimulatedStand, axis: str, model: str = "keysight-53230a",
                 host: str = "127.0.0.1", port: int = 0, *, signal_channel: int = 1,
                 signal_low_v: float = 0.0, signal_high_v: float = 5.0,
                 sync: SyncLink | None = None, timeout_s: float | None = None,
                 seed: int = 0, external_reference: bool = True,
                 first_value: str = "from-start", timebase_offset_rel: float = 0.0) -> None:
        self.profile: CounterProfile = get_profile(model)
        super().__init__(idn=self.profile.idn, host=host, port=port)
        if self.profile.maker.startswith("Keysight"):  # `+0,"No error"` (Prog. Ref.)
            self.error_code_format = "{:+d}"
        if first_value not in FIRST_VALUE_READINGS:
            raise ValueError(f"counter twin first_value {first_value!r}: one of "
                             f"{', '.join(FIRST_VALUE_READINGS)}")
        #: how the 53230A's first timestamp value is read (counter_profiles,
        #: MANUAL_FIRST_VALUE): from the start event, or edge to edge (the manual's
        #: SENSe:TSTamp:RATE example); each plausible reading is a setting
        self.first_value = first_value
        self.stand = stand
        self.axis = stand.axis(axis)
        self.clock = stand.clock
        self.signal_channel = signal_channel
        self.signal_v = (float(signal_low_v), float(signal_high_v))
        self.inputs: dict[int, InputState] = {}
        self.acquisition: TwinAcquisition | None = None
        self.sync = sync
        #: a valid 10 MHz at Ext Ref In (the stand's GPS-disciplined reference)
        self.external_reference = external_reference
        #: the timebase in use; SENS:ROSC:SOUR is not reset by *RST here (simplification:
        #: the manual's *RST value of the auto selection is not modelled; the CNT-91 starts
        #: the same way, its power-on selection not being known to us)
        self.reference = "EXT" if external_reference else "INT"
        #: the time base's true offset e (issue 58): every interval the counter times from
        #: its start event reads (1 + e) times the true one; 0, the stand's time exactly
        self.timebase_offset_rel = float(timebase_offset_rel)
        self.rng = np.random.default_rng(seed)
        #: SYST:TIM, non-volatile: not touched by *RST (None: disabled, as shipped)
        self.timeout_s: float | None = timeout_s
        self.reset()
        self._route_words()
        if self.profile.model == "keysight-53230a":
            self._route_script_words()
        elif self.profile.model == "pendulum-cnt-91":
            self._route_cnt91_words()

    # -- state ----------------------------------------------------------------------------
    def reset(self) -> None:
        self.inputs = {ch: InputState() for ch in self.profile.channels}
        self.function: str | None = None
        self.function_channel = 1
        self.sample_count = 1
        self.trigger_source = "IMM"
        self.timestamp_info = False
        self.timestamp_rate_hz = 1.0e6
        self.gate = "DEF"
        self.acquisition = None
        # 53230A *RST values (Programmer's Reference: TRIG:COUN 1, TRIG:DEL 0,
        # TRIG:SLOP NEG, FORM ASC, FORM:BORD NORM, FREQ:MODE AUTO)
        self.trigger_count = 1
        self.trigger_delay_s = 0.0
        self.trigger_slope = "NEG"
        self.data_format = "ASC"
        self.ascii_digits = 15
        self.byte_order = "NORM"
        self.frequency_mode = "AUTO"
        self.invert = False
        self.tint_channels = (1, 2)      # CONF:TINT: start and stop channels
        self.totalize_gate_s = 0.1       # CONF:TOT:TIM gate (DEF 0.1 s)
        self.ts_layout = "stst"          # CNT-91: STSTamp or TSTAmp replies
        if self.profile.model == "keysight-53230a":  # *RST function: FREQ 1
            self.function, self.invert = "periods", True
        # CNT-91 (Programmer's Handbook): gate 10 ms, single measurements, arming IMM
        self.aperture_s = 0.01
        self.walk = self.back_to_back = self.continuous = False
        self.arm_source, self.arm_slope, self.arm_count = "IMM", "POS", 1
        self.interpolator_auto = True

    def pending(self) -> bool:
        return self.acquisition is not None and not self._progress(self.acquisition)

    def session_ended(self) -> None:
        self.acquisition = None  # a measurement dies with its client (simplification)

    # -- the measurement ------------------------------------------------------------------
    def _sees_edges(self, channel: int) -> bool:
        s = self.inputs[channel]
        low, high = self.signal_v
        return channel == self.signal_channel and not s.level_auto and low < s.level_v < high

    def _per_init(self) -> int:
        """Readings one INIT makes: SAMP:COUN x TRIG:COUN, at most the memory's."""
        return min(self.sample_count * self.trigger_count, KEYSIGHT_53230A_MEMORY
                   if self.profile.model == "keysight-53230a" else self.profile.max_count)

    def _start_source(self) -> str:
        """What starts a measurement after INIT: 'imm', 'sync' (the FOG's sync pulse at
        the external input it is wired to) or 'bus' (*TRG)."""
        if self.profile.model == "pendulum-cnt-91":
            # start arming (CNT-90 series Programmer's Handbook, :ARM:SOURce): the sync
            # is wired to the rear arming input E (EXT4); A and B carry the signals
            if self.arm_source in ("EXT1", "EXT2"):
                raise ExecError(-221, "Settings conflict;start arming on input A or B is "
                                      "not modelled by this twin")
            return "sync" if self.arm_source == "EXT4" else "imm"
        return {"EXT": "sync", "BUS": "bus"}.get(self.trigger_source, "imm")

    def _arm(self, kind: Kind, n: int) -> TwinAcquisition:
        ch = self.function_channel
        source = self._start_source()
        blind = self.take_fault("no-trigger") or not self._sees_edges(ch)
        t_arm = self.clock.now()
        t_start = t_arm
        if source == "sync":
            if self.sync is None:
                blind = True  # nothing is wired to the external trigger input
            else:
                t_start = self.sync.next_pulse_s(t_arm, self.rng)
        elif source == "bus":
            t_start = math.inf  # the first *TRG (53220A/53230A Prog. Ref. TRIG:SOUR BUS)
        bus = source == "bus"
        self.acquisition = TwinAcquisition(
            kind, n, ch, t_arm, self.timeout_s, blind, t_start,
            edge_to_edge=(kind == "timestamps" and self.first_value == "edge-to-edge"
                          and self.profile.timestamps == "keysight-tst"),
            invert=kind == "periods" and self.invert,
            walk=kind == "periods" and self.walk,
            gate_s=self.totalize_gate_s if kind == "totals" else self.aperture_s,
            back_to_back=self.back_to_back, bus=bus,
            blocks=max(1, n // max(self.sample_count, 1)) if bus else 1,
            waiting_trigger=bus)
        self.last_acquisition = self.acquisition  # kept after the client leaves (tests)
        return self.acquisition

    def _bus_trigger(self, a: Mapping[str, str]) -> None:
        """*TRG (IEEE 488.2 10.37): with TRIG:SOUR BUS, starts the readings of one trigger
        of a measurement INIT left waiting for it; anything else is -211 "Trigger
        ignored" (SCPI-99 vol. 2, 21.8.10), as is a trigger while a block is measured."""
        acq = self.acquisition
        if acq is None or not acq.bus or self.trigger_source != "BUS" \
                or self._progress(acq) or not acq.waiting_trigger:
            raise ExecError(-211, "Trigger ignored")
        now = self.clock.now()
        if not acq.triggers:
            acq.t_start_s = now
        acq.triggers.append(now)
        acq.waiting_trigger = False

    def _select(self, acq: TwinAcquisition
                ) -> tuple[np.ndarray, np.ndarray, float, bool]:
        """The edges the readings use so far; for each, the stand time it began to be
        waited for (the previous edge, or its block's start); that time for the next
        edge; and whether the next reading waits for a trigger (*TRG), not an edge.

        One block (IMM, EXT): the first edges after the start event. With TRIG:SOUR BUS
        each trigger's readings take the first edges after the later of that trigger
        and the end of the previous trigger's readings."""
        edges = acq.edges_s
        start0 = max(acq.t_start_s, acq.t_arm_s)
        if not acq.bus:
            chosen = edges[:acq.edges_needed]
            refs = np.concatenate([[start0], chosen[:-1]])[:chosen.size]
            return chosen, refs, float(chosen[-1]) if chosen.size else start0, False
        per = (acq.n // acq.blocks) * acq.edges_per_reading
        parts: list[np.ndarray] = []
        refs_parts: list[np.ndarray] = []
        prev_end, next_ref = -math.inf, start0
        for k in range(acq.blocks):
            if k >= len(acq.triggers):
                return _cat(parts), _cat(refs_parts), next_ref, True
            start = max(acq.triggers[k], prev_end)
            extra = acq.edges_needed - acq.n * acq.edges_per_reading if k == 0 else 0
            i = int(np.searchsorted(edges, start, side="right"))
            block = edges[i:i + per + extra]
            parts.append(block)
            refs_parts.append(np.concatenate([[start], block[:-1]])[:block.size])
            next_ref = float(block[-1]) if block.size else start
            if block.size < per + extra:
                break
            prev_end = next_ref
        return _cat(parts), _cat(refs_parts), next_ref, False

    def _progress(self, acq: TwinAcquisition) -> bool:
        """Bring the acquisition up to the clock's now; True once its readings exist."""
        if acq.values is not None:
            return True
        if acq.bus and not acq.triggers:
            return False  # INIT waits for *TRG
        now = self.clock.now()
        if not acq.blind and now > acq.t_start_s:
            self.axis.advance_to(now)
            acq.edges_s = self.axis.zero_marks(acq.t_start_s, now).t_edge_s
        if acq.kind == "totals":
            if now < acq.t_start_s + acq.n * acq.gate_s:
                return False
            acq.values = self._totals(acq, acq.n)
            return True
        if acq.walk:
            readings = self._walk(acq)
            if readings.size < acq.n:
                return False
            acq.values = readings[:acq.n]
            return True
        chosen, refs, next_ref, waiting = self._select(acq)
        acq.waiting_trigger = waiting
        # per reading (p. 459): the next stamp must come within the timeout of the last
        late = (np.flatnonzero(chosen - refs > acq.timeout_s) if acq.timeout_s is not None
                else np.empty(0, int))
        if late.size:
            chosen = chosen[:int(late[0])]
        timed_out = acq.timeout_s is not None and not waiting and (
            late.size > 0 or now >= next_ref + acq.timeout_s)
        if chosen.size < acq.edges_needed and not timed_out:
            return False
        values = self._values(acq, chosen)
        acq.values = np.concatenate([values, np.full(acq.n - values.size, SCPI_NAN)])
        return True

    def _values(self, acq: TwinAcquisition, chosen: np.ndarray) -> np.ndarray:
        """The readings the chosen edges make, as the instrument resolves them."""
        edges = self.profile.quantise(self._counter_time(acq, chosen))
        if acq.kind == "timestamps":
            if acq.edge_to_edge:
                if edges.size:
                    acq.stamp0_s = float(edges[0])
                elif acq.stamp0_s is None:
                    acq.stamp0_s = acq.t_start_s
                return edges[1:]
            return edges
        pairs = edges.size // 2
        values = edges[1:2 * pairs:2] - edges[0:2 * pairs:2]
        return 1.0 / values if acq.invert else values

    def _counter_time(self, acq: TwinAcquisition, t_s: np.ndarray) -> np.ndarray:
        """Stand times as this counter's time base reads them: every interval from the
        start event scaled by 1 + e (docs/method.md A1, the timebase; issue 58). With
        e = 0 the times are returned untouched, to the bit."""
        if self.timebase_offset_rel == 0.0:
            return t_s
        t0 = acq.t_start_s if math.isfinite(acq.t_start_s) else 0.0
        return t0 + (np.asarray(t_s, dtype=float) - t0) * (1.0 + self.timebase_offset_rel)

    def _totals(self, acq: TwinAcquisition, n: int) -> np.ndarray:
        """Totalize, timed (53220A/53230A CONFigure:TOTalize:TIMed): the edges counted in
        each of n gates, back to back from the start event (gate dead time not
        modelled)."""
        bounds = acq.t_start_s + acq.gate_s * np.arange(n + 1)
        return np.diff(np.searchsorted(acq.edges_s, bounds, side="left")).astype(float)

    def _walk(self, acq: TwinAcquisition) -> np.ndarray:
        """Gated readings from the edges so far: each from an edge to the first edge at
        least the gate time later (a reciprocal counter's measurement, CNT-90 series
        Programmer's Handbook, :ACQuisition:APERture), frequency = turns / time."""
        e = self.profile.quantise(self._counter_time(acq, acq.edges_s))
        out: list[float] = []
        i = 0
        while len(out) < acq.n and i < e.size:
            later = np.flatnonzero(e[i + 1:] - e[i] >= acq.gate_s)
            if not later.size:
                break
            j = i + 1 + int(later[0])
            span, turns = e[j] - e[i], j - i
            out.append(turns / span if acq.invert else span / turns)
            i = j if acq.back_to_back else j + 1
        return np.array(out)

    def _available(self, acq: TwinAcquisition) -> np.ndarray:
        """The readings that exist now (all of them once the acquisition is done): what
        R?, DATA:REM? and DATA:POIN? see of the reading memory."""
        if self._progress(acq):
            assert acq.values is not None
            return acq.values
        if acq.bus and not acq.triggers:
            return np.empty(0)
        if acq.kind == "totals":
            done = int((self.clock.now() - acq.t_start_s) // acq.gate_s)
            return self._totals(acq, max(0, min(done, acq.n)))
        if acq.walk:
            return self._walk(acq)
        chosen, _, _, _ = self._select(acq)
        return self._values(acq, chosen)

    def _readings(self, acq: TwinAcquisition | None) -> np.ndarray:
        if acq is None:
            raise ExecError(-230, "Data corrupt or stale")
        self.wait(lambda: self._progress(acq))
        assert acq.values is not None
        return acq.values

    def _encode(self, acq: TwinAcquisition, values: np.ndarray, first: int = 0) -> str:
        p = self.profile
        if acq.kind == "timestamps":
            fmt = TIMESTAMP_FORMATS[p.timestamps or ""]
            if fmt.name == "pendulum-stst" and not self.timestamp_info \
                    and self.ts_layout == "stst":
                return ",".join(str(i + 1) for i in range(values.size))
            nan = values >= 0.999 * SCPI_NAN
            stamp0 = acq.t_start_s if acq.stamp0_s is None else acq.stamp0_s
            digits = (self.ascii_digits - 1 if fmt.name == "keysight-tst"  # intervals
                      else self._time_digits(values[~nan] - stamp0))
            if fmt.name == "pendulum-stst" and not self.timestamp_info:
                # CNT-91 TSTAmp without FORM:TINF: the time stamps alone (unverified
                # layout, see the profile's notes)
                text = ",".join(profile_nr3(t - stamp0, digits, p.reply_exp_digits)
                                for t in np.where(nan, stamp0, values))
            else:
                text = fmt.encode(np.where(nan, stamp0, values), stamp0, digits,
                                  p.reply_exp_digits, first)
            return _nan_tail(text, int(nan.sum()))
        digits = self.ascii_digits - 1 if p.model == "keysight-53230a" else p.reply_digits
        return encode_values(values, digits, p.reply_exp_digits)

    def _reply(self, acq: TwinAcquisition, values: np.ndarray, first: int = 0, *,
               fetch: bool = False) -> str | bytes:
        """ASCII (FORM ASC), or FORM REAL: 8-byte doubles in a block (`_formatted`);
        `fetch`: the reply of FETC? or READ?."""
        return self._formatted(self._encode(acq, values, first), fetch=fetch)

    def _formatted(self, text: str, *, fetch: bool = False) -> str | bytes:
        """The readings as FORMat[:DATA] says. REAL on the 53230A (Programmer's
        Reference, FORMat[:DATA]): IEEE 754 doubles, byte order FORM:BORD (NORMal:
        big-endian); FETC? and READ? answer an indefinite-length block, `#0<bytes>`
        then the terminator, as the FORMat:DATA page shows; R? (and DATA:REM?) a
        definite-length one. REAL on the CNT-91 (CNT-90 series Programmer's Handbook,
        :FORMat[:DATA]): big-endian doubles in a definite-length block."""
        if self.data_format != "REAL":
            return text
        numbers = parse_numbers(text)
        keysight = self.profile.model == "keysight-53230a"
        big = not keysight or self.byte_order == "NORM"
        data = numbers.astype(">f8" if big else "<f8").tobytes()
        return b"#0" + data if keysight and fetch else _block(data)

    def _time_digits(self, t_s: np.ndarray) -> int:
        """Digits after the point that carry the resolution (up to 17 significant):
        times on an axis of hours need more than the 15 a period needs."""
        finite = np.abs(t_s[t_s < SCPI_NAN])
        t_max = float(finite.max()) if finite.size else 1.0
        span = math.floor(math.log10(max(t_max, 1e-300))) \
            - math.floor(math.log10(self.profile.resolution_s))
        return int(min(16, max(self.profile.reply_digits, span + 1)))

    # -- routes: one handler per word the profile has --------------------------------------
    def _route_words(self) -> None:
        self.route_words(self.profile.words, {
            "input_coupling": (self._set_coupling, lambda a: self._inp(a).coupling),
            "input_impedance": (self._set_impedance, lambda a: self._nr3(self._inp(a).impedance_ohm)),
            "input_level_auto": (self._set_level_auto,
                                 lambda a: bool_reply(self._inp(a).level_auto)),
            "input_level": (self._set_level, lambda a: self._nr3(self._inp(a).level_v)),
            "input_slope": (self._set_slope, lambda a: self._inp(a).slope),
            "configure_timestamps": (self._conf_timestamps, None),
            "configure_period": (self._conf_period, None),
            "timestamp_rate": (self._set_rate, lambda a: self._nr3(self.timestamp_rate_hz)),
            "timestamp_info": (self._set_tinf, lambda a: bool_reply(self.timestamp_info)),
            "sample_count": (self._set_count, lambda a: f"+{self.sample_count}"),
            "gate_time": (self._set_gate, None),
            "measurement_timeout": (self._set_timeout, lambda a: self._nr3(
                9.9e37 if self.timeout_s is None else self.timeout_s)),  # p. 459: 9.9E37
            "format_data": (self._set_format, lambda a: self.data_format),
            "trigger_source": (self._set_trigger_source, lambda a: (
                self.arm_source if self.profile.model == "pendulum-cnt-91"
                else self.trigger_source)),
            "reference_source": (self._set_reference, lambda a: self.reference),
            "reference_check": (self._check_reference, None),
            "abort": (self._abort, None),
            "initiate": (self._initiate, None),
            "fetch": (None, self._fetch, True),
            "fetch_array": (None, self._fetch_array, True),
            "read": (None, self._read, True),
        })

    def _nr3(self, value: float) -> str:
        """A setting's query reply as the model prints it: `+1.00000000E+006` (53230A
        Programmer's Reference p. 377, p. 459)."""
        return profile_nr3(value, 8, self.profile.reply_exp_digits)

    def _inp(self, a: Mapping[str, str]) -> InputState:
        return suffix_item(self.inputs, a)

    def _set_coupling(self, a: Mapping[str, str]) -> None:
        self._inp(a).coupling = enum_param(a["coupling"], self.profile.couplings)

    def _set_impedance(self, a: Mapping[str, str]) -> None:
        z = number_param(a["impedance_ohm"], {"MIN": min(self.profile.impedances_ohm),
                                              "MAX": max(self.profile.impedances_ohm),
                                              "DEF": 1.0e6})
        if not any(math.isclose(z, x) for x in self.profile.impedances_ohm):
            raise ExecError(-224, "Illegal parameter value")
        self._inp(a).impedance_ohm = z

    def _set_level_auto(self, a: Mapping[str, str]) -> None:
        state = a["state"].upper()
        if state == "ONCE":  # one auto-level on a pulse this slow finds nothing useful
            self._inp(a).level_auto = False
            return
        self._inp(a).level_auto = bool_param(state)

    def _set_level(self, a: Mapping[str, str]) -> None:
        v = ranged_param(a["level_v"], *self.profile.level_range_v, default=0.0)
        inp = self._inp(a)
        inp.level_v, inp.level_auto = v, False  # a level given turns auto-level off

    def _set_slope(self, a: Mapping[str, str]) -> None:
        self._inp(a).slope = enum_param(a["slope"], ("POSitive", "NEGative"))

    def _channel_list(self, a: Mapping[str, str]) -> int:
        ch = int(number_param(a["channel"], {}))
        if ch not in self.profile.channels:
            raise ExecError(-222, "Data out of range")
        return ch

    def _conf_timestamps(self, a: Mapping[str, str]) -> None:
        count = count_param(a["count"], self.profile.max_count, default=100)
        self.function, self.function_channel = "timestamps", self._channel_list(a)
        self.sample_count = count
        self.timestamp_info = True  # CONF turns the timestamp information on (CNT-91)
        self.ts_layout = "stst"
        self.acquisition = None

    def _conf_period(self, a: Mapping[str, str]) -> None:
        self.function, self.function_channel = "periods", self._channel_list(a)
        self.sample_count = 1
        self.invert = False
        self.acquisition = None

    def _set_rate(self, a: Mapping[str, str]) -> None:
        rate = number_param(a["rate_hz"], {"MIN": 1e4, "MAX": 1e6, "DEF": 1e6})
        if not any(math.isclose(rate, r) for r in (1e4, 1e5, 8e5, 1e6)):
            raise ExecError(-224, "Illegal parameter value")
        self.timestamp_rate_hz = rate

    def _set_tinf(self, a: Mapping[str, str]) -> None:
        self.timestamp_info = bool_param(a["state"])

    def _set_count(self, a: Mapping[str, str]) -> None:
        self.sample_count = count_param(a["count"], self.profile.max_count)

    def _set_gate(self, a: Mapping[str, str]) -> None:
        self.gate = a["gate_s"]  # one period per reading whatever the gate: turns are slow

    def _set_timeout(self, a: Mapping[str, str]) -> None:
        lo, hi = self.profile.measurement_timeout_range_s or (0.0, math.inf)
        value = a["timeout_s"].upper()
        if value.startswith("INF"):
            self.timeout_s = None
            return
        self.timeout_s = ranged_param(value, lo, hi, default=1.0)

    def _set_reference(self, a: Mapping[str, str]) -> None:
        if self.profile.model != "pendulum-cnt-91":
            self.reference = enum_param(a["source"], ("INTernal", "EXTernal"))
            return
        # CNT-91 [:SENSe]:ROSCillator:SOURce {INTernal|EXTernal|AUTO} (unverified, see
        # the profile's notes): EXTernal with no valid signal at the reference input is
        # an error here (the model has no check word), and the source stays as it was
        source = enum_param(a["source"], ("INTernal", "EXTernal", "AUTO"))
        if source == "EXT" and not self.external_reference:
            raise ExecError(-241, "Hardware missing;no valid external reference signal")
        self.reference = source

    def _check_reference(self, a: Mapping[str, str]) -> None:
        """SENS:ROSC:EXT:CHEC ONCE: an error when no valid signal is at Ext Ref In."""
        if enum_param(a["when"], ("ONCE",)) and not self.external_reference:
            raise ExecError(-241, "Hardware missing; no valid external timebase")

    def _set_trigger_source(self, a: Mapping[str, str]) -> None:
        if self.profile.model == "pendulum-cnt-91":   # the start arming source
            self._set_arm_source({"raw": a["source"]})
            return
        self.trigger_source = enum_param(a["source"], ("IMMediate", "EXTernal", "BUS"))

    def _set_format(self, a: Mapping[str, str]) -> None:
        """FORMat[:DATA] {ASCii|REAL} (CNT-90 series Programmer's Handbook); PACKed is
        not modelled (-224)."""
        fmt = enum_param(a["format"], ("ASCii", "REAL", "PACKed"))
        if fmt == "PACK":
            raise ExecError(-224, "Illegal parameter value")
        self.data_format = fmt

    def _abort(self, a: Mapping[str, str]) -> None:
        self.acquisition = None

    def _kind(self) -> Kind:
        """What INIT / READ? measure; -221 for a function set but not modelled (a clear
        error, not a wrong number)."""
        if self.function is None:
            raise ExecError(-221, "Settings conflict")
        if self.function == "tint":
            raise ExecError(-221, "Settings conflict;time interval (CONF:TINT) is not "
                                  "modelled by this twin")
        return self.function  # type: ignore[return-value]

    def _initiate(self, a: Mapping[str, str]) -> None:
        kind = self._kind()
        if self.pending():
            raise ExecError(-213, "Init ignored")
        self._arm(kind, self._per_init())

    def _fetch(self, a: Mapping[str, str]) -> str | bytes:
        acq = self.acquisition
        values = self._readings(acq)
        assert acq is not None
        return self._reply(acq, values, fetch=True)

    def _fetch_array(self, a: Mapping[str, str]) -> str | bytes:
        acq = self.acquisition
        values = self._readings(acq)
        assert acq is not None
        count = a["count"].upper()
        left = values.size - acq.fetched
        limit = self.profile.fetch_max_results or values.size
        n = min(left, limit) if count.startswith("MAX") else int(number_param(count, {}))
        if not 1 <= n <= min(left, limit):
            raise ExecError(-222, "Data out of range")
        first = acq.fetched
        acq.fetched += n
        return self._reply(acq, values[first:first + n], first)

    def _read(self, a: Mapping[str, str]) -> str | bytes:
        kind = self._kind()
        if self._start_source() == "bus":
            # READ? (ABORt, INIT, FETCh?) cannot be followed by the *TRG it would wait
            # for: SCPI-99 vol. 2, 21.8.10, -214 "Trigger deadlock"
            raise ExecError(-214, "Trigger deadlock")
        acq = self._arm(kind, self._per_init())
        return self._reply(acq, self._readings(acq), fetch=True)

    # -- 53230A words users' own scripts send (counter_profiles.Keysight53230aScriptWords)
    def _route_script_words(self) -> None:
        """The 53230A as the public client programs script it (Programmer's Reference:
        MEASure, CONFigure, DATA, FORMat, TRIGger subsystems; R?, *LRN?, *STB?)."""
        w = KEYSIGHT_53230A_SCRIPT_WORDS
        # first: ahead of the profile's templated forms
        self.route(w.format_data, on_set=self._set_format_raw, on_query=lambda a: (
            f"ASC,{self.ascii_digits}" if self.data_format == "ASC" else "REAL,64"),
            first=True, raw=True)
        self.route(w.configure_period, on_set=lambda a: self._conf_scalar(a, invert=False),
                   first=True, raw=True)
        self.route(w.configure_frequency, on_set=lambda a: self._conf_scalar(a, invert=True),
                   raw=True)
        self.route(w.configure_timestamp, on_set=self._conf_tst, raw=True)
        self.route(w.measure_period, on_query=lambda a: self._measure_scalar(a, False),
                   data=True, raw=True)
        self.route(w.measure_frequency, on_query=lambda a: self._measure_scalar(a, True),
                   data=True, raw=True)
        self.route(w.measure_timestamps, on_query=self._measure_tst, data=True, raw=True)
        self.route(w.read_remove, on_query=self._r_query, data=True, raw=True)
        self.route(w.data_remove, on_query=self._data_remove, data=True, raw=True)
        self.route(w.data_points, on_query=lambda a: f"+{len(self._memory())}")
        self.route(w.configure_query, on_query=self._conf_query)
        self.route(w.learn, on_query=self._learn)
        self.route(w.status_byte, on_query=lambda a: f"+{4 if self.errors else 0}")
        self.route(w.scpi_version, on_query=lambda a: "1994.0")
        # TRIG:COUN? / SAMP:COUN? [MIN|MAX|DEF] (Programmer's Reference, TRIGger:COUNt
        # and SAMPle:COUNt: 1 to 1,000,000, default 1)
        self.route(w.trigger_count, on_set=self._set_trigger_count, on_query=lambda a: (
            _count_query(a["raw"], self.trigger_count, KEYSIGHT_53230A_COUNT_MAX)),
            raw=True)
        self.route(w.sample_count, on_set=self._set_sample_count_raw, on_query=lambda a: (
            _count_query(a["raw"], self.sample_count, KEYSIGHT_53230A_COUNT_MAX)),
            first=True, raw=True)
        self.route(w.trigger_delay, on_set=self._set_trigger_delay,
                   on_query=self._trigger_delay_query, raw=True)
        # IEEE 488.2 *TRG: the bus trigger TRIG:SOUR BUS waits for (TRIGger:SOURce page)
        self.route(TRG, on_set=self._bus_trigger)
        self.route(w.configure_time_interval, on_set=self._conf_tint, raw=True)
        self.route(w.configure_totalize_timed, on_set=self._conf_totalize, raw=True)
        self.route(w.trigger_slope, on_set=lambda a: setattr(
            self, "trigger_slope", enum_param(a["raw"], ("POSitive", "NEGative"))),
            on_query=lambda a: self.trigger_slope, raw=True)
        self.route(w.byte_order, on_set=lambda a: setattr(
            self, "byte_order", enum_param(a["raw"], ("NORMal", "SWAPped"))),
            on_query=lambda a: self.byte_order, raw=True)
        self.route(w.frequency_mode, on_set=lambda a: setattr(
            self, "frequency_mode", enum_param(a["raw"], ("AUTO", "CONTinuous",
                                                          "RCONtinuous", "RECiprocal"))),
            on_query=lambda a: self.frequency_mode, raw=True)

    def _nr3_15(self, value: float) -> str:
        return profile_nr3(value, 14, self.profile.reply_exp_digits)

    def _set_format_raw(self, a: Mapping[str, str]) -> None:
        """FORMat[:DATA] ASCii[,<digits 1..15>] | REAL[,64]."""
        kind, _, length = a["raw"].partition(",")
        fmt = enum_param(kind, ("ASCii", "REAL"))
        if fmt == "ASC":
            digits = int(number_param(length, {"MIN": 1, "MAX": 15, "DEF": 15})) \
                if length.strip() else 15
            if not 1 <= digits <= 15:
                raise ExecError(-222, "Data out of range")
            self.data_format, self.ascii_digits = "ASC", digits
        else:
            if length.strip() and int(number_param(length, {"DEF": 64})) != 64:
                raise ExecError(-224, "Illegal parameter value")
            self.data_format = "REAL"

    def _scalar_channel(self, raw: str) -> int:
        """`[<expected>,<resolution>,](@<ch>)` or nothing (channel 1): the channel."""
        text = raw.replace(" ", "")
        parts = [p for p in text.split(",") if p] if text else []
        chan = 1
        if parts and parts[-1].startswith("(@"):
            chan = self._channel_list({"channel": parts.pop().strip("(@)")})
        if len(parts) > 2:
            raise ExecError(-108, "Parameter not allowed")
        for p in parts:  # expected value and resolution: numbers, MIN, MAX or DEF
            number_param(p, {"MIN": 0.0, "MAX": 0.0, "DEF": 0.0})
        return chan

    def _conf_scalar(self, a: Mapping[str, str], invert: bool) -> None:
        self.function_channel = self._scalar_channel(a["raw"])
        self.function, self.sample_count, self.invert = "periods", 1, invert
        self.trigger_count = 1
        self.acquisition = None

    def _measure_scalar(self, a: Mapping[str, str], invert: bool) -> str | bytes:
        self._conf_scalar(a, invert)
        return self._read({})

    def _conf_tst(self, a: Mapping[str, str]) -> None:
        """CONFigure:TSTamp [{<count>|MIN|MAX|DEF}][,(@<ch>)] (the reference's example:
        `CONF:TST (5000)`); a count sets the readings (SAMP:COUN), none leaves them."""
        count, chan = self._count_and_channel(a["raw"], KEYSIGHT_53230A_MEMORY)
        self.function, self.function_channel = "timestamps", chan
        if count is not None:
            self.sample_count = count
        self.acquisition = None

    def _count_and_channel(self, raw: str, high: int, default: int = 1
                           ) -> tuple[int | None, int]:
        """`[(<count>) | <count>][,(@<ch>)]`: the count (None if absent) and channel (1)."""
        items = _split_params(raw)
        chan = 1
        if items and items[-1].startswith("(@"):
            chan = self._channel_list({"channel": items.pop().strip("(@)")})
        if len(items) > 1:
            raise ExecError(-108, "Parameter not allowed")
        count = count_param(items[0].strip("()"), high, default) if items else None
        return count, chan

    def _conf_tint(self, a: Mapping[str, str]) -> None:
        """CONFigure:TINTerval [(@<start>),(@<stop>)] (53220A/53230A Programmer's
        Reference; default (@1),(@2)). Configured and reported by CONF?; measuring it is
        not modelled (INIT, READ? give -221)."""
        items = _split_params(a["raw"])
        if len(items) > 2:
            raise ExecError(-108, "Parameter not allowed")
        if any(not i.startswith("(@") for i in items):
            raise ExecError(-224, "Illegal parameter value")
        chans = [self._channel_list({"channel": i.strip("(@)")}) for i in items] or [1, 2]
        self.tint_channels = (chans[0], chans[-1])   # one list: start and stop on it
        self.function, self.function_channel = "tint", self.tint_channels[0]
        self.sample_count = self.trigger_count = 1
        self.acquisition = None

    def _conf_totalize(self, a: Mapping[str, str]) -> None:
        """CONFigure:TOTalize:TIMed [<gate>,][(@<ch>)] (53220A/53230A Programmer's
        Reference): edges counted in a gate; DEF 0.1 s (gate range assumed 1e-5 to
        1000 s, unverified). Each reading is the zero marks in one gate."""
        items = _split_params(a["raw"])
        chan = 1
        if items and items[-1].startswith("(@"):
            chan = self._channel_list({"channel": items.pop().strip("(@)")})
        if len(items) > 1:
            raise ExecError(-108, "Parameter not allowed")
        gate = ranged_param(items[0], 1e-5, 1000.0, 0.1) if items else 0.1
        self.function, self.function_channel, self.totalize_gate_s = "totals", chan, gate
        self.sample_count = self.trigger_count = 1
        self.acquisition = None

    def _measure_tst(self, a: Mapping[str, str]) -> str | bytes:
        count, _, chan = a["raw"].replace(" ", "").partition("),(")
        self._conf_timestamps({"count": count.strip("()"), "channel": chan.strip("(@)")
                               if chan else "1"})
        return self._read({})

    def _memory(self) -> list[str]:
        """The reading memory not yet removed, as the instrument would print each item.
        For timestamps the prescaler is the first item (count+1 elements, User's Guide
        'Time stamp'), so DATA:POIN? counts it and a removal may take it."""
        acq = self.acquisition
        if acq is None:
            return []
        values = self._available(acq)
        items = self._encode(acq, values).split(",") if values.size else []
        return items[acq.removed:]

    def _remove(self, n: int) -> str | bytes:
        acq = self.acquisition
        assert acq is not None
        items = self._memory()[:n]
        acq.removed += len(items)
        return self._formatted(",".join(items))

    def _r_query(self, a: Mapping[str, str]) -> bytes:
        """R? [<max>]: the readings in memory (at most max), removed, as a definite-length
        block; `#10` when there are none (joewhalen/keysight_53230A counter.py)."""
        raw = a["raw"].strip()
        limit = int(number_param(raw, {"MIN": 1, "MAX": KEYSIGHT_53230A_MEMORY,
                                       "DEF": KEYSIGHT_53230A_MEMORY})) if raw else None
        n = len(self._memory())
        n = n if limit is None else min(n, limit)
        if n == 0:
            return b"#10"
        reply = self._remove(n)
        return reply if isinstance(reply, bytes) else _block(reply.encode("ascii"))

    def _data_remove(self, a: Mapping[str, str]) -> str | bytes:
        """DATA:REMove? <n>[,WAIT]: n readings removed; with WAIT, once they exist; without,
        -230 when fewer are in memory (opronningen/53230A-Toolkit R/R.cs)."""
        count, _, wait = a["raw"].replace(" ", "").partition(",")
        n = count_param(count, KEYSIGHT_53230A_MEMORY)
        if self.acquisition is None:
            raise ExecError(-230, "Data corrupt or stale")
        if wait:
            enum_param(wait, ("WAIT",))
            self.wait(lambda: len(self._memory()) >= n)
        elif len(self._memory()) < n:
            raise ExecError(-230, "Data corrupt or stale")
        return self._remove(n)

    def _conf_query(self, a: Mapping[str, str]) -> str:
        """CONFigure?: the function and channel, quoted (unverified layout)."""
        if self.function == "tint":
            start, stop = self.tint_channels
            return f'"TINT (@{start}),(@{stop})"'
        if self.function == "totals":
            return (f'"TOT:TIM {self._nr3_15(self.totalize_gate_s)},'
                    f'(@{self.function_channel})"')
        name = {"timestamps": "TST", "periods": "FREQ" if self.invert else "PER"}.get(
            self.function or "", "FREQ")
        return f'"{name} (@{self.function_channel})"'

    def _set_trigger_count(self, a: Mapping[str, str]) -> None:
        self.trigger_count = _count_set(a["raw"], KEYSIGHT_53230A_COUNT_MAX)

    def _set_sample_count_raw(self, a: Mapping[str, str]) -> None:
        self.sample_count = _count_set(a["raw"], KEYSIGHT_53230A_COUNT_MAX)

    def _set_trigger_delay(self, a: Mapping[str, str]) -> None:
        if count_params(a["raw"]) > 1:
            raise ExecError(-108, "Parameter not allowed")
        self.trigger_delay_s = ranged_param(a["raw"], 0.0, 3600.0, 0.0)

    def _trigger_delay_query(self, a: Mapping[str, str]) -> str:
        """TRIG:DEL? [MIN|MAX|DEF]: 0 to 3600 s, default 0."""
        raw = a["raw"].strip()
        if not raw:
            return self._nr3_15(self.trigger_delay_s)
        if count_params(raw) > 1:
            raise ExecError(-108, "Parameter not allowed")
        which = enum_param(raw, ("MINimum", "MAXimum", "DEFault"))
        return self._nr3_15({"MIN": 0.0, "MAX": 3600.0, "DEF": 0.0}[which])

    def _learn(self, a: Mapping[str, str]) -> str:
        """*LRN?: the settings as the commands that restore them, `;`-separated, as
        opronningen/53230A-Toolkit's LearnConfig splits them."""
        parts = ["*RST", f":TRIG:SOUR {self.trigger_source}",
                 f":TRIG:SLOP {self.trigger_slope}", f":TRIG:COUN +{self.trigger_count}",
                 f":TRIG:DEL {self._nr3_15(self.trigger_delay_s)}",
                 f":SAMP:COUN +{self.sample_count}",
                 "FORM " + (f"ASC,{self.ascii_digits}" if self.data_format == "ASC"
                            else "REAL,64"),
                 f"FORM:BORD {self.byte_order}", f":FREQ:MODE {self.frequency_mode}",
                 f":TST:RATE {self._nr3_15(self.timestamp_rate_hz)}"]
        for ch, inp in sorted(self.inputs.items()):
            parts += [f":INP{ch}:COUP {inp.coupling}", f":INP{ch}:IMP "
                      f"{self._nr3_15(inp.impedance_ohm)}", f":INP{ch}:SLOP {inp.slope}",
                      f":INP{ch}:LEV:AUTO {'ON' if inp.level_auto else 'OFF'}"]
            if not inp.level_auto:
                parts.append(f":INP{ch}:LEV {self._nr3_15(inp.level_v)}")
        return ";".join(parts)

    # -- CNT-91 words PyMeasure's driver sends (counter_profiles.Cnt91ScriptWords) ------
    def _route_cnt91_words(self) -> None:
        w = CNT91_SCRIPT_WORDS
        smax = self.profile.fetch_max_results or self.profile.max_count
        self.route(w.format_smax, on_query=lambda a: str(smax))
        self.route(w.continuous, on_set=lambda a: setattr(
            self, "continuous", _scpi_bool(a["raw"])),
            on_query=lambda a: bool_reply(self.continuous), raw=True)
        self.route(w.aperture, on_set=lambda a: setattr(
            self, "aperture_s", ranged_param(a["raw"], 2e-8, 1000.0, 0.01)),
            on_query=lambda a: self._nr3(self.aperture_s), raw=True)
        self.route(w.arm_source, on_set=self._set_arm_source,
                   on_query=lambda a: self.arm_source, raw=True)
        self.route(w.arm_slope, on_set=lambda a: setattr(
            self, "arm_slope", enum_param(a["raw"], ("POSitive", "NEGative"))),
            on_query=lambda a: self.arm_slope, raw=True)
        self.route(w.arm_count, on_set=lambda a: setattr(
            self, "arm_count", count_param(a["raw"], 2_000_000_000)),
            on_query=lambda a: str(self.arm_count), raw=True)
        self.route(w.interpolator_auto, on_set=lambda a: setattr(
            self, "interpolator_auto", _scpi_bool(a["raw"])),
            on_query=lambda a: bool_reply(self.interpolator_auto), raw=True)
        self.route(w.configure_frequency_array_btb,
                   on_set=lambda a: self._conf_gated(a, invert=True, array=True, btb=True),
                   raw=True)
        self.route(w.configure_frequency_array,
                   on_set=lambda a: self._conf_gated(a, invert=True, array=True, btb=False),
                   raw=True)
        self.route(w.configure_frequency, on_set=lambda a: self._conf_gated(
            a, invert=True, array=False, btb=False), raw=True)
        self.route(w.configure_period, on_set=lambda a: self._conf_gated(
            a, invert=False, array=False, btb=False), raw=True)
        self.route(w.measure_frequency, on_query=lambda a: self._measure_gated(a, True),
                   data=True, raw=True)
        self.route(w.measure_period, on_query=lambda a: self._measure_gated(a, False),
                   data=True, raw=True)
        self.route(w.read, on_query=self._read, data=True)
        self.route(w.fetch, on_query=self._fetch, data=True)
        self.route(w.status_byte, on_query=lambda a: str(4 if self.errors else 0))
        self.route(w.options, on_query=lambda a: "0")  # IEEE 488.2 10.20: none
        # :MEASure:ARRay:STSTamp? (p. 8-72) and :MEASure:ARRay:TSTAmp?, :CONF:ARR:TSTAmp
        self.route(w.measure_single_timestamps, on_query=lambda a: self._measure_ts(
            a, "stst"), data=True, raw=True)
        self.route(w.measure_timestamps, on_query=lambda a: self._measure_ts(a, "tsta"),
                   data=True, raw=True)
        self.route(w.configure_timestamps, on_set=lambda a: self._conf_ts(a, "tsta"),
                   raw=True)

    def _conf_ts(self, a: Mapping[str, str], layout: str) -> None:
        """:CONF:ARR:STSTamp / :CONF:ARR:TSTAmp (<n>)[,(@<ch>)]: n time stamps. STST turns
        FORM:TINF on (X,TS pairs, p. 8-72); TSTA leaves it (TS alone while it is off)."""
        count, chan = self._count_and_channel(a["raw"], self.profile.max_count, 100)
        if count is None:
            raise ExecError(-109, "Missing parameter")
        self._conf_timestamps({"count": str(count), "channel": str(chan)})
        self.ts_layout = layout
        if layout == "tsta":
            self.timestamp_info = False

    def _measure_ts(self, a: Mapping[str, str], layout: str) -> str | bytes:
        info = self.timestamp_info
        self._conf_ts(a, layout)
        if layout == "tsta":
            self.timestamp_info = info
        return self._read({})

    def _set_arm_source(self, a: Mapping[str, str]) -> None:
        src = a["raw"].strip().upper()
        names = {"IMM": "IMM", "IMMEDIATE": "IMM", "EXT1": "EXT1", "EXTERNAL1": "EXT1",
                 "EXT2": "EXT2", "EXTERNAL2": "EXT2", "EXT4": "EXT4", "EXTERNAL4": "EXT4"}
        if src not in names:
            raise ExecError(-224, "Illegal parameter value")
        self.arm_source = names[src]

    def _conf_gated(self, a: Mapping[str, str], *, invert: bool, array: bool,
                    btb: bool) -> None:
        """CONF:ARR:FREQ[:BTB] <n>,(@ch), CONF:FREQ [(@ch)], CONF:PER [(@ch)]."""
        text = a["raw"].replace(" ", "")
        count, chan = "1", text
        if array:
            count, _, chan = text.partition(",")
        self.sample_count = count_param(count, self.profile.max_count)
        self.function_channel = self._channel_list({"channel": chan.strip("(@)")}) \
            if chan else 1
        self.function, self.invert, self.walk, self.back_to_back = "periods", invert, True, btb
        self.acquisition = None

    def _measure_gated(self, a: Mapping[str, str], invert: bool) -> str | bytes:
        self._conf_gated(a, invert=invert, array=False, btb=False)
        return self._read({})


def _split_params(raw: str) -> list[str]:
    """A parameter text's parameters (commas outside parentheses), blanks removed."""
    text = raw.replace(" ", "")
    if not text:
        return []
    out, depth, cur = [], 0, ""
    for ch in text:
        depth += (ch == "(") - (ch == ")")
        if ch == "," and depth == 0:
            out.append(cur)
            cur = ""
        else:
            cur += ch
    return [*out, cur]


def _count_set(raw: str, high: int) -> int:
    """A count setting: one of 1..high, MIN, MAX, DEF; more than one parameter is -108
    (SCPI-99 vol. 2, 21.8.9), none -109."""
    n = count_params(raw)
    if n == 0:
        raise ExecError(-109, "Missing parameter")
    if n > 1:
        raise ExecError(-108, "Parameter not allowed")
    return count_param(raw, high)


def _count_query(raw: str, current: int, high: int, default: int = 1) -> str:
    """A count's query, `?` alone (the setting) or `? MIN|MAX|DEF` (its limits)."""
    n = count_params(raw)
    if n == 0:
        return f"+{current}"
    if n > 1:
        raise ExecError(-108, "Parameter not allowed")
    which = enum_param(raw, ("MINimum", "MAXimum", "DEFault"))
    return f"+{ {'MIN': 1, 'MAX': high, 'DEF': default}[which] }"


def _cat(parts: list[np.ndarray]) -> np.ndarray:
    return np.concatenate(parts) if parts else np.empty(0)


def _nan_tail(text: str, n_nan: int) -> str:
    """Replace the last n values of a reply by 9.91E37 (readings that timed out)."""
    if n_nan == 0:
        return text
    parts = text.split(",")
    parts[len(parts) - n_nan:] = [nr3(SCPI_NAN)] * n_nan
    return ",".join(parts)


def _block(data: bytes) -> bytes:
    """IEEE 488.2 definite-length arbitrary block: `#<digits><length><data>`."""
    length = str(len(data))
    return f"#{len(length)}{length}".encode("ascii") + data


def _scpi_bool(text: str) -> bool:
    """A SCPI boolean: ON/OFF, or a number (non-zero is ON once rounded, SCPI-99 7.3)."""
    t = text.strip().upper()
    if t in ("ON", "OFF"):
        return t == "ON"
    return round(number_param(t, {})) != 0
