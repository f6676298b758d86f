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
- READ? (generic counter): one period, from the first edge after the READ? arrived.

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
    FIRST_VALUE_READINGS,
    TIMESTAMP_FORMATS,
    CounterProfile,
    encode_values,
    get_profile,
)
from drivers.counter_profiles import nr3 as profile_nr3
from drivers.scpi import SCPI_NAN
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


@dataclass
class TwinAcquisition:
    """A measurement in progress (or done) on the twin."""

    kind: Literal["timestamps", "periods"]
    n: int                      # readings
    channel: int
    t_arm_s: float              # stand time of INIT / READ?
    timeout_s: float | None     # the instrument's own per-reading timeout, virtual s
    blind: bool                 # no edges reach the counter (set-up or 'no-trigger')
    t_start_s: float = 0.0      # the start event: INIT, or the sync pulse (TRIG:SOUR EXT)
    values: np.ndarray | None = None
    edges_s: np.ndarray = field(default_factory=lambda: np.empty(0))
    fetched: int = 0            # results already sent by FETC:ARR?
    #: stamp 0: the start event, or (first_value "edge-to-edge") the first edge after it
    edge_to_edge: bool = False
    stamp0_s: float | None = None

    @property
    def edges_needed(self) -> int:
        if self.kind == "timestamps":
            return self.n + (1 if self.edge_to_edge else 0)
        return 2 * self.n


class CounterTwin(ScpiServer):
    """A counter of `model` watching the zero mark of `stand.axes[axis]`."""

    fault_names = ScpiServer.fault_names | {"no-trigger"}

    def __init__(self, stand: SimulatedStand, axis: str, model: str = "keysight-53230a",
                 host: str = "127.0.0.1", port: int = 0, *, signal_channel: int = 1,
                 signal_low_v: float = 0.0, signal_high_v: float = 5.0,
                 sync: SyncLink | None = None, timeout_s: float | None = None,
                 seed: int = 0, external_reference: bool = True,
                 first_value: str = "from-start") -> None:
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
        #: the manual's *RST value of the auto selection is not modelled)
        self.reference = "EXT" if external_reference else "INT"
        self.rng = np.random.default_rng(seed)
        #: SYST:TIM, non-volatile: not touched by *RST (None: disabled, as shipped)
        self.timeout_s: float | None = timeout_s
        self.reset()
        self._route_words()

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

    def pending(self) -> bool:
        return self.acquisition is not None and not self._progress(self.acquisition)

    def session_ended(self) -> None:
        self.acquisition = None  # a measurement dies with its client (simplification)

    # -- the measurement ------------------------------------------------------------------
    def _sees_edges(self, channel: int) -> bool:
        s = self.inputs[channel]
        low, high = self.signal_v
        return channel == self.signal_channel and not s.level_auto and low < s.level_v < high

    def _arm(self, kind: Literal["timestamps", "periods"], n: int) -> TwinAcquisition:
        ch = self.function_channel
        blind = self.take_fault("no-trigger") or not self._sees_edges(ch)
        t_arm = self.clock.now()
        t_start = t_arm
        if self.trigger_source == "EXT":
            if self.sync is None:
                blind = True  # nothing is wired to the external trigger input
            else:
                t_start = self.sync.next_pulse_s(t_arm, self.rng)
        self.acquisition = TwinAcquisition(
            kind, n, ch, t_arm, self.timeout_s, blind, t_start,
            edge_to_edge=(kind == "timestamps" and self.first_value == "edge-to-edge"
                          and self.profile.timestamps == "keysight-tst"))
        self.last_acquisition = self.acquisition  # kept after the client leaves (tests)
        return self.acquisition

    def _progress(self, acq: TwinAcquisition) -> bool:
        """Bring the acquisition up to the clock's now; True once its readings exist."""
        if acq.values is not None:
            return True
        now = self.clock.now()
        if not acq.blind and now > acq.t_start_s:
            self.axis.advance_to(now)
            acq.edges_s = self.axis.zero_marks(acq.t_start_s, now).t_edge_s
        need = acq.edges_needed
        # per reading (p. 459): the next stamp must come within the timeout of the last
        stamps = np.concatenate([[max(acq.t_start_s, acq.t_arm_s)], acq.edges_s[:need]])
        late = (np.flatnonzero(np.diff(stamps) > acq.timeout_s) if acq.timeout_s is not None
                else np.empty(0, int))
        if late.size:
            acq.edges_s = acq.edges_s[:int(late[0])]
        timed_out = acq.timeout_s is not None and (
            late.size > 0 or now >= stamps[-1] + acq.timeout_s)
        if acq.edges_s.size < need and not timed_out:
            return False
        edges = self.profile.quantise(acq.edges_s[:need])
        if acq.kind == "timestamps" and acq.edge_to_edge:
            acq.stamp0_s = float(edges[0]) if edges.size else acq.t_start_s
            values = edges[1:]
        elif acq.kind == "timestamps":
            values = edges
        else:
            pairs = edges.size // 2
            values = edges[1:2 * pairs:2] - edges[0:2 * pairs:2]
        acq.values = np.concatenate([values, np.full(acq.n - values.size, SCPI_NAN)])
        return True

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
            if fmt.name == "pendulum-stst" and not self.timestamp_info:
                return ",".join(str(i + 1) for i in range(values.size))
            nan = values >= 0.999 * SCPI_NAN
            stamp0 = acq.t_start_s if acq.stamp0_s is None else acq.stamp0_s
            text = fmt.encode(np.where(nan, stamp0, values), stamp0,
                              self._time_digits(values[~nan] - stamp0),
                              p.reply_exp_digits, first)
            return _nan_tail(text, int(nan.sum()))
        return encode_values(values, p.reply_digits, p.reply_exp_digits)

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
            "format_data": (self._set_format, lambda a: "ASC"),
            "trigger_source": (self._set_trigger_source, lambda a: self.trigger_source),
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
        self.acquisition = None

    def _conf_period(self, a: Mapping[str, str]) -> None:
        self.function, self.function_channel = "periods", self._channel_list(a)
        self.sample_count = 1
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
        self.reference = enum_param(a["source"], ("INTernal", "EXTernal"))

    def _check_reference(self, a: Mapping[str, str]) -> None:
        """SENS:ROSC:EXT:CHEC ONCE: an error when no valid signal is at Ext Ref In."""
        if enum_param(a["when"], ("ONCE",)) and not self.external_reference:
            raise ExecError(-241, "Hardware missing; no valid external timebase")

    def _set_trigger_source(self, a: Mapping[str, str]) -> None:
        self.trigger_source = enum_param(a["source"], ("IMMediate", "EXTernal", "BUS"))

    def _set_format(self, a: Mapping[str, str]) -> None:
        if enum_param(a["format"], ("ASCii", "REAL", "PACKed")) != "ASC":
            raise ExecError(-224, "Illegal parameter value")  # the twin speaks ASCII only

    def _abort(self, a: Mapping[str, str]) -> None:
        self.acquisition = None

    def _initiate(self, a: Mapping[str, str]) -> None:
        if self.function is None:
            raise ExecError(-221, "Settings conflict")
        if self.pending():
            raise ExecError(-213, "Init ignored")
        kind = "timestamps" if self.function == "timestamps" else "periods"
        self._arm(kind, self.sample_count)  # type: ignore[arg-type]

    def _fetch(self, a: Mapping[str, str]) -> str:
        acq = self.acquisition
        values = self._readings(acq)
        assert acq is not None
        return self._encode(acq, values)

    def _fetch_array(self, a: Mapping[str, str]) -> str:
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
        return self._encode(acq, values[first:first + n], first)

    def _read(self, a: Mapping[str, str]) -> str:
        if self.function is None:
            raise ExecError(-221, "Settings conflict")
        kind = "timestamps" if self.function == "timestamps" else "periods"
        acq = self._arm(kind, self.sample_count)  # type: ignore[arg-type]
        return self._encode(acq, self._readings(acq))


def _nan_tail(text: str, n_nan: int) -> str:
    """Replace the last n values of a reply by 9.91E37 (readings that timed out)."""
    if n_nan == 0:
        return text
    parts = text.split(",")
    parts[len(parts) - n_nan:] = [nr3(SCPI_NAN)] * n_nan
    return ",".join(parts)
