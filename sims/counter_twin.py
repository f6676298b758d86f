"""The frequency counter's twin: times the simulated stand's zero mark over real SCPI.

It speaks the words of one counter profile (drivers/counter_profiles.py, imported, not
copied) on a TCP socket (sims/scpi_server.py) and answers from the stand's truth: on INIT
(or READ?) it notes the stand clock's now() as the arm time; the readings are the next
zero-mark edges after it (`AxisModel.zero_marks(...).t_edge_s`, which carry the slot
sensor's jitter), on the stand's time axis, rounded to the profile's resolution (20 ps
for the 53230A). It waits in real time until the virtual clock has passed the last edge
it reports, so a driver sees the same timing a real counter would give it, sped up.

The twin is built in layers, each a module of its own, each reading only the ones below:
its state, settings and the measurement in progress (sims/counter_state.py), the
measurement engine and its replies (sims/counter_engine.py), the command table of the
profile's words (sims/counter_commands.py), the tables of the words users' own scripts
send (sims/counter_53230a.py, sims/counter_cnt91.py). Where the models differ beyond
their profile's words, the twin reads its model's TwinProfile (sims/counter_models.py).

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

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from drivers.counter_profiles import FIRST_VALUE_READINGS, get_profile
from drivers.counter_settings import CounterSettings as StandCounter
from sims.counter_53230a import Keysight53230aScript
from sims.counter_cnt91 import Cnt91Script
from sims.counter_models import twin_profile
from sims.counter_state import InputState, Kind, SyncLink, TwinAcquisition
from sims.scpi_server import ScpiServer
from sims.stand import SimulatedStand
from sims.truth import AxisTruth

__all__ = ["CounterTwin", "InputState", "Kind", "SyncLink", "TwinAcquisition",
           "ZeroMarkSignal"]


@dataclass(frozen=True)
class ZeroMarkSignal:
    """How the zero mark reaches the counter: the input it is wired to and the levels it
    swings between (a trigger level outside them, or another input, sees no edges)."""

    channel: int = 1
    low_v: float = 0.0
    high_v: float = 5.0


class CounterTwin(Cnt91Script, Keysight53230aScript):
    """A counter of `settings.model` watching the zero mark of `stand.axes[axis]`."""

    fault_names = ScpiServer.fault_names | {"no-trigger"}

    def __init__(self, stand: SimulatedStand, axis: str, settings: StandCounter,
                 truth: AxisTruth | None = None, *, sync: SyncLink | None = None,
                 seed: int = 0, timeout_s: float | None = None,
                 signal: ZeroMarkSignal = ZeroMarkSignal(), host: str = "127.0.0.1",
                 port: int = 0) -> None:
        """`settings`: the stand's counter block, as the driver takes it (its model names
        the profile the twin speaks); `truth`: the axis's truth (default: the stand's),
        whose counter parts the twin reads whole (the reference wired to it, how its
        first timestamp reads, its time base's offset, the serial it reports)."""
        t = truth if truth is not None else stand.axis(axis).truth
        self.profile = get_profile(settings.model)
        self.twin_profile = twin_profile(self.profile)
        idn = self.profile.idn
        if t.serials.counter:    # the stand's serial in *IDN? field 3
            fields = idn.split(",")
            idn = ",".join([*fields[:2], t.serials.counter, *fields[3:]])
        super().__init__(idn=idn, host=host, port=port)
        self.error_code_format = self.twin_profile.error_code_format
        first_value = t.counter_first_value
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
        self.signal_channel = signal.channel
        self.signal_v = (float(signal.low_v), float(signal.high_v))
        self.inputs: dict[int, InputState] = {}
        self.acquisition: TwinAcquisition | None = None
        self.sync = sync
        #: a valid 10 MHz at Ext Ref In (the stand's GPS-disciplined reference)
        self.external_reference = t.counter_external_reference
        #: the timebase in use; SENS:ROSC:SOUR is not reset by *RST here (simplification:
        #: the manual's *RST value of the auto selection is not modelled; the CNT-91 starts
        #: the same way, its power-on selection not being known to us)
        self.reference = "EXT" if self.external_reference else "INT"
        #: the time base's true offset e (issue 58): every interval the counter times from
        #: its start event reads (1 + e) times the true one; 0, the stand's time exactly
        self.timebase_offset_rel = float(t.counter.timebase_offset_rel)
        self.rng = np.random.default_rng(seed)
        #: SYST:TIM, non-volatile: not touched by *RST (None: disabled, as shipped)
        self.timeout_s: float | None = timeout_s
        self.reset()
        self._route_words()
        if self.twin_profile.script_words is not None:
            SCRIPT_WORDS[self.twin_profile.script_words](self)

    def session_ended(self) -> None:
        self.acquisition = None  # a measurement dies with its client (simplification)


#: TwinProfile.script_words -> the command table it names
SCRIPT_WORDS: dict[str, Callable[[CounterTwin], None]] = {
    "keysight-53230a": CounterTwin._route_script_words,
    "pendulum-cnt-91": CounterTwin._route_cnt91_words,
}
