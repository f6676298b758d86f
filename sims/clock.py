"""The simulated stand's clocks: the only clocks any twin reads.

Two kinds. `SteppedClock` (the default for twins, `sim: clock_speed: max` or no key) is a
conservative co-simulation: virtual time passes only while the bench waits on the clock,
and only once every twin and every driver reader has finished reacting to what the
previous instant held. `VirtualClock` (`clock_speed: N`) is paced by wall time, for
rehearsals in front of an operator; results then depend on how the machine schedules.

Co-simulation (SteppedClock). The participants are:
- the bench thread(s), which advance time by waiting on the clock (`sleep`,
  `sleep_until`); the drivers turn each wait for an instrument (a reply, N frames, a
  settle, a measurement complete) into such waits when the clock says `stepped`
  (drivers/waits.py), so a wait ends at a virtual time fixed by the data, never by
  thread scheduling;
- the twins, joined with `join(participant)`: each says when its next event is
  (`next_event_s`: the drive's next TPDO tick), is told when time reaches it
  (`advance(t)`, called in the waiting thread, so every twin acts at exactly that t), and
  says whether it has delivered what [0, t] holds (`settled(t, final)`);
- the channels between them: a twin counts what it put on a channel
  (`sent(name, n)`: bytes on a pty, TPDOs on a CAN bus), a driver what it consumed
  (`consumed(name, n)`, through drivers/clock.py, so drivers import nothing from sims).
  A channel is drained when its consumer has taken all that was sent.

A step: all participants settled at t, then t jumps to the earliest of the waiting
thread's target, every participant's next event and `t + max_step_s`; each participant
advances to it. Between the steps of one wait a streaming channel (the FOG's bytes) may
trail by its lead (a bounded backlog, so the twin encodes while the driver decodes);
when the wait ends every channel is drained: what the bench reads at time t is exactly
what the stand produced up to t, on any machine, at any load. A streaming twin joined
with `drained_on_read=channel` is drained when its driver reads (`settle_channel`,
drivers/clock.py, called by every reading of the driver) instead of at the end of every
wait: the bench's settles and turn timing wait on the drives' TPDOs many times a second
of stand time and read no FOG sample, and draining the FOG's pty at each of them (a
hand-off through two threads and the kernel's pty worker) was half the demo's measuring
time (issue 62). What a reading sees is the same: everything up to now. A participant that does not
settle within `GUARD_REAL_S` of real time (a dead twin, a reader gone) is reported once
and passed over: a broken twin cannot freeze the run.

A step hands work from thread to thread (the stepping thread, a twin's writer, a
driver's reader, the CAN notifier): `GIL_SWITCH_S` is the interpreter's switch interval
while a stepped clock runs (SimBench sets it), so a hand-off does not wait the default
5 ms behind a thread decoding frames.

Heartbeats and their watchdogs stay in real time (drivers/heartbeat.py): they guard
the link, not the measurement, and their tests are about real-time behaviour.

The paced clock (VirtualClock), as before:

Virtual seconds run up to `top_speed` times faster than real ones, so a ladder that would
take hours on a real table takes minutes. Twins never keep a clock of their own; they ask
this one, so the counter's zero marks, the FOG's samples and the drive's ramp all live on
one time axis.

Pacing. A twin that streams (the FOG) registers a pacer: a function saying up to which
virtual time it has delivered its data. The clock then never runs more than `lead_s`
ahead of the slowest pacer, so a twin that cannot keep up (a loaded machine, a slow
reader) slows the clock instead of leaving its reader waiting for data "that should
have arrived". With `top_speed = inf` (`sim: clock_speed: max`) the twins alone set the
pace: the stand runs as fast as every twin keeps up. A fixed speed stays available: it
is a cap, and without pacers the clock runs exactly at it. Whatever the pacers say, the
clock never runs slower than `floor_speed` (real time by default: a real bench's pace),
so a twin that died cannot freeze the run, and `min_speed` is a speed every real-time
budget for failure detection can rely on. Pacing twins that nobody reads (the bench is
closing) hold the clock at that floor: nothing is measured, and the drive twins' CAN
threads are not made to generate hours of stand samples while they answer the stop.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from drivers import interrupts

log = logging.getLogger(__name__)

#: `sim: clock_speed: max`
MAX = "max"
#: virtual seconds a paced clock may run ahead of the slowest twin's delivered data
DEFAULT_LEAD_S = 20.0
#: the paced clock never runs slower than real time (the pace of a real bench)
REAL_TIME = 1.0
#: "max" on a stand with no twin that paces (nothing streams): a finite top speed all the same
UNPACED_MAX_SPEED = 500.0
_SPEED_WINDOW_REAL_S = 0.5   # real seconds over which the running speed is measured
_POLL_MAX_REAL_S = 0.02      # a paced sleep looks at the clock at least this often
_POLL_MIN_REAL_S = 0.0005

#: a pacer: the virtual time (s) up to which a twin has delivered its output
Pacer = Callable[[], float]


def parse_speed(value: float | str | None, default: float | str = MAX) -> float:
    """`sim: clock_speed` as a top speed: a number > 0, or "max" (inf)."""
    v = default if value is None else value
    if isinstance(v, str):
        if v.strip().lower() == MAX:
            return math.inf
        raise ValueError(f"clock speed must be a number > 0 or {MAX!r}, got {v!r}")
    speed = float(v)
    if not speed > 0:
        raise ValueError(f"clock speed must be > 0, got {v}")
    return speed


class VirtualClock:
    """Virtual time, advanced at `top_speed` in real time unless a pacer holds it back."""

    def __init__(self, speed: float | str = 1.0, start_s: float = 0.0, running: bool = True,
                 *, lead_s: float = DEFAULT_LEAD_S, floor_speed: float = REAL_TIME) -> None:
        self.top_speed = parse_speed(speed)
        if not lead_s > 0:
            raise ValueError(f"clock lead must be > 0, got {lead_s}")
        self.lead_s = float(lead_s)
        self.floor_speed = min(float(floor_speed), self.top_speed)
        self._lock = threading.Lock()
        self._t_s = float(start_s)
        self._m_last: float | None = time.monotonic() if running else None
        self._pacers: list[Pacer] = []
        top = self.top_speed if math.isfinite(self.top_speed) else UNPACED_MAX_SPEED
        self._measured = (self._m_last, self._t_s, top)  # (real, virtual, speed) of the window

    # -- speeds -------------------------------------------------------------------------
    @property
    def speed(self) -> float:
        """Virtual seconds per real second, as the clock runs now (for estimates).

        A fixed-speed clock without pacers runs exactly at its speed; a paced one reports
        its measured pace over the last half second of real time.
        """
        if not self._pacers and math.isfinite(self.top_speed):
            return self.top_speed
        return self._measured[2]

    @property
    def min_speed(self) -> float:
        """The slowest this clock can run: real-time budgets for failures divide by it."""
        return self.floor_speed if self._pacers else self.speed

    @property
    def paced(self) -> bool:
        return bool(self._pacers)

    def pace(self, pacer: Pacer) -> Callable[[], None]:
        """Hold the clock within `lead_s` of what `pacer` has delivered; returns the undo."""
        with self._lock:
            self._advance_locked()
            self._pacers.append(pacer)

        def unpace() -> None:
            with self._lock:
                self._advance_locked()
                if pacer in self._pacers:
                    self._pacers.remove(pacer)
        return unpace

    # -- time ---------------------------------------------------------------------------
    def start(self) -> None:
        """Let a paused clock run: the simulated bench starts every twin first, then this."""
        with self._lock:
            if self._m_last is None:
                self._m_last = time.monotonic()
                self._measured = (self._m_last, self._t_s, self._measured[2])

    def pause(self) -> None:
        """Stop the clock where it is (the simulated bench stopped: no twin runs)."""
        with self._lock:
            self._advance_locked()
            self._m_last = None

    @property
    def running(self) -> bool:
        return self._m_last is not None

    def now(self) -> float:
        with self._lock:
            return self._advance_locked()

    def _advance_locked(self) -> float:
        if self._m_last is None:
            return self._t_s
        m = time.monotonic()
        dt_real = m - self._m_last
        self._m_last = m
        free = self._t_s + self.top_speed * dt_real if dt_real > 0 else self._t_s
        if not math.isfinite(free):
            free = self._t_s + UNPACED_MAX_SPEED * dt_real
        limit = min((p() for p in self._pacers), default=math.inf) + self.lead_s
        if math.isfinite(limit):  # a twin streams: stay within lead_s of its data
            t_new = max(self._t_s + self.floor_speed * dt_real, min(free, limit))
        elif self._pacers:  # twins that pace, but nobody reads them (closing): no hurry
            t_new = self._t_s + self.floor_speed * dt_real
        else:
            t_new = free
        self._t_s = max(self._t_s, t_new)
        m0, t0, speed = self._measured
        if m0 is not None and m - m0 >= _SPEED_WINDOW_REAL_S:
            self._measured = (m, self._t_s, max((self._t_s - t0) / (m - m0), self.floor_speed))
        return self._t_s

    def sleep(self, duration_s: float) -> None:
        """Sleep `duration_s` virtual seconds."""
        if duration_s <= 0:
            return
        if (not self._pacers and math.isfinite(self.top_speed)) or not self.running:
            time.sleep(duration_s / self.speed)
            return
        self.sleep_until(self.now() + duration_s)

    def sleep_until(self, t_s: float) -> None:
        if (not self._pacers and math.isfinite(self.top_speed)) or not self.running:
            self.sleep(t_s - self.now())
            return
        while (left := t_s - self.now()) > 0:
            time.sleep(min(max(left / self.speed, _POLL_MIN_REAL_S), _POLL_MAX_REAL_S))

    def real_seconds(self, virtual_s: float) -> float:
        """The longest a virtual interval can take in real time (for real-time timeouts)."""
        return virtual_s / self.min_speed


#: `sim: clock_speed` values that select the co-simulation (SteppedClock)
STEPPED_SPEEDS = (math.inf,)
#: longest single jump of a stepped clock (virtual s): bounds what a twin encodes at once
DEFAULT_MAX_STEP_S = 30.0
#: the interpreter's thread switch interval while a stepped clock runs (s; default 0.005)
GIL_SWITCH_S = 0.0005
#: real seconds a stepped clock waits for a participant to settle before passing it over
GUARD_REAL_S = 20.0
_SETTLE_POLL_REAL_S = 0.002


class Participant(Protocol):
    """A twin in the co-simulation (see the module docstring)."""

    def next_event_s(self, t_s: float) -> float:
        """The next virtual time after `t_s` at which it must act (inf: none)."""
        ...

    def advance(self, t_s: float) -> None:
        """Time is now `t_s`: produce what [.., t_s] holds (called in the waiting thread)."""
        ...

    def settled(self, t_s: float, final: bool) -> bool:
        """Its output up to `t_s` is delivered and consumed (`final`: fully; else within
        its lead)."""
        ...


@dataclass
class _Channel:
    sent: int = 0
    consumed: int = 0
    open: bool = False


class SteppedClock:
    """Virtual time that passes only in waits, when every participant is settled."""

    stepped = True
    paced = False
    #: real-time budgets (drivers/clock.py) treat a stepped clock's seconds as real ones:
    #: generous, since a stepped stand runs far faster than real time
    min_speed = REAL_TIME

    def __init__(self, start_s: float = 0.0, running: bool = True, *,
                 max_step_s: float = DEFAULT_MAX_STEP_S) -> None:
        if not max_step_s > 0:
            raise ValueError(f"max_step_s must be > 0, got {max_step_s}")
        self.max_step_s = float(max_step_s)
        self.top_speed = math.inf
        self._t_s = float(start_s)
        self._running = running
        self._cond = threading.Condition()
        self._stepper: threading.Thread | None = None
        self._targets: dict[int, float] = {}
        self._participants: list[Participant] = []
        #: participants drained when their driver reads (channel name -> participant)
        self._on_read: dict[str, Participant] = {}
        self._channels: dict[str, _Channel] = {}
        self._passed_over: set[int] = set()
        self._progress = threading.Condition(threading.Lock())
        self._generation = 0
        self._m0 = time.monotonic()
        self._t0 = self._t_s
        self.steps = 0
        self.settle_wait_real_s = 0.0   # real time spent waiting for participants (profile)

    # -- what the drivers and the engine see -------------------------------------------
    @property
    def speed(self) -> float:
        """Virtual seconds per real second so far (an estimate for progress displays)."""
        dt = time.monotonic() - self._m0
        v = (self._t_s - self._t0) / dt if dt > 0 else 0.0
        return max(v, REAL_TIME)

    @property
    def running(self) -> bool:
        return self._running

    def start(self) -> None:
        with self._cond:
            self._running = True

    def pause(self) -> None:
        with self._cond:
            self._running = False
            self._cond.notify_all()

    def now(self) -> float:
        return self._t_s

    def drain(self) -> None:
        """Return once every participant has delivered what [0, now] holds, as at the end
        of any wait. An instrument opened since the last wait (a FOG whose twin sends the
        frames due so far as soon as it is read) is otherwise drained by thread
        scheduling, and the bench's first look at it would depend on the machine's load."""
        if self._running:
            with interrupts.shelter():
                self._settle(self._t_s, final=True)
            interrupts.safe_point()

    def settle_channel(self, name: str) -> None:
        """A driver is about to read channel `name`: return once its twin has delivered
        what [0, now] holds (a twin joined with `drained_on_read=name`; any other channel
        is drained at the end of every wait already). A thread other than the one
        stepping the clock (a display) reads as the steps leave it, as before."""
        with self._cond:
            p = self._on_read.get(name)
            busy = self._stepper is not None and self._stepper is not threading.current_thread()
        if p is None or busy or not self._running:
            return
        with interrupts.shelter():
            self._settle(self._t_s, final=True, parts=[p])
        interrupts.safe_point()

    def real_seconds(self, virtual_s: float) -> float:
        return virtual_s / self.min_speed

    def pace(self, pacer: Pacer) -> Callable[[], None]:
        """Pacers belong to the wall-time clock; a stepped clock's twins settle instead."""
        return lambda: None

    # -- channels ----------------------------------------------------------------------
    def channel_opened(self, name: str) -> None:
        with self._cond:
            ch = self._channels.setdefault(name, _Channel())
            ch.open, ch.sent, ch.consumed = True, 0, 0

    def channel_closed(self, name: str) -> None:
        with self._cond:
            ch = self._channels.get(name)
            if ch is not None:
                ch.open = False
            self._cond.notify_all()

    def sent(self, name: str, n: int) -> None:
        """A twin put `n` units on channel `name` (counted while a consumer has it open)."""
        with self._cond:
            ch = self._channels.get(name)
            if ch is not None and ch.open:
                ch.sent += n

    def consumed(self, name: str, n: int) -> None:
        with self._cond:
            ch = self._channels.setdefault(name, _Channel(open=True))
            ch.consumed += n
        self.poke()

    def poke(self) -> None:
        """Something a participant's `settled` depends on changed: look again now."""
        with self._progress:
            self._generation += 1
            self._progress.notify_all()

    def has_consumer(self, name: str) -> bool:
        with self._cond:
            ch = self._channels.get(name)
            return ch is not None and ch.open

    def backlog(self, name: str) -> int:
        """Units sent on `name` not yet consumed (0 when no consumer has it open)."""
        with self._cond:
            ch = self._channels.get(name)
            return max(ch.sent - ch.consumed, 0) if ch is not None and ch.open else 0

    def join(self, participant: Participant, *,
             drained_on_read: str | None = None) -> Callable[[], None]:
        """Add a twin to the co-simulation; returns the undo. `drained_on_read`: the
        channel whose driver drains it when reading (`settle_channel`), not every wait."""
        with self._cond:
            self._participants.append(participant)
            if drained_on_read is not None:
                self._on_read[drained_on_read] = participant

        def leave() -> None:
            with self._cond:
                if participant in self._participants:
                    self._participants.remove(participant)
                if drained_on_read is not None \
                        and self._on_read.get(drained_on_read) is participant:
                    del self._on_read[drained_on_read]
        return leave

    # -- waiting -----------------------------------------------------------------------
    def sleep(self, duration_s: float) -> None:
        if duration_s > 0:
            self.sleep_until(self._t_s + duration_s)

    def sleep_until(self, t_s: float) -> None:
        """Let virtual time pass to `t_s`, stepping every participant on the way."""
        me = threading.get_ident()
        if not self._running:
            # a paused clock: nothing runs (before the bench starts, after it stops);
            # a wait on it returns at once, time standing still, as on a paused stand
            return
        with interrupts.shelter():  # a Ctrl-C is raised between steps, never in a lock
            self._sleep_until(me, t_s)
        interrupts.safe_point()

    def _sleep_until(self, me: int, t_s: float) -> None:
        try:
            while True:
                interrupts.safe_point()  # here this thread holds no lock
                with self._cond:
                    if self._t_s >= t_s or not self._running:
                        break
                    self._targets[me] = t_s
                    if self._stepper is not None and self._stepper is not threading.current_thread():
                        self._cond.wait(0.05)
                        continue
                    self._stepper = threading.current_thread()
                    target = min(self._targets.values())
                try:
                    self._step_towards(target)
                finally:
                    with self._cond:
                        self._stepper = None
                        self._cond.notify_all()
            with self._cond:   # drained when read (settle_channel): as the last step left them
                parts = [p for p in self._participants if p not in self._on_read.values()]
            self._settle(self._t_s, final=True, parts=parts)
        finally:
            with self._cond:
                self._targets.pop(me, None)

    def _step_towards(self, target: float) -> None:
        t = self._t_s
        self._settle(t, final=False)
        with self._cond:
            parts = list(self._participants)
        t_next = min([target, t + self.max_step_s]
                     + [p.next_event_s(t) for p in parts])
        t_next = max(t_next, math.nextafter(t, math.inf))
        with self._cond:
            self._t_s = t_next
            self.steps += 1
        for p in parts:
            p.advance(t_next)

    def _settle(self, t: float, final: bool, parts: list[Participant] | None = None) -> None:
        if parts is None:
            with self._cond:
                parts = list(self._participants)
        m0 = time.monotonic()
        for p in parts:
            while True:
                gen = self._generation
                if interrupts.deferred() or p.settled(t, final):
                    break  # (a Ctrl-C: the stop needs the clock more than the settle)
                if time.monotonic() - m0 > GUARD_REAL_S:
                    if id(p) not in self._passed_over:
                        self._passed_over.add(id(p))
                        log.warning("stepped clock: %r did not settle at t = %.6f s within "
                                    "%.0f s of real time; passed over", p, t, GUARD_REAL_S)
                    break

                def moved_on(g: int = gen) -> bool:
                    return self._generation != g

                with self._progress:  # woken by consumed()/poke(), else look again soon
                    self._progress.wait_for(moved_on, _SETTLE_POLL_REAL_S)
        self.settle_wait_real_s += time.monotonic() - m0


def make_clock(speed: float, running: bool = True) -> VirtualClock | SteppedClock:
    """The clock a `sim: clock_speed` asks for: max (inf) co-simulates, N paces."""
    if speed in STEPPED_SPEEDS:
        # runs from the start: its time passes only in waits, so nothing moves before the
        # bench waits, and TPDOs the bench's opening waits for come in clock steps (a
        # real-time tick would interleave them with the bench's writes by scheduling)
        return SteppedClock(running=True)
    return VirtualClock(speed, running=running)
