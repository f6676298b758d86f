"""drivers/interrupts.py: a Ctrl-C during a co-simulation step never leaves a lock held.

Real parts: the engine's SignalGuard installed as the SIGINT handler, a real SIGINT sent
to this process, the co-simulation's SteppedClock. Only the twin is a stand-in: a
participant that takes a lock by hand, the way `threading.Condition.__enter__` does, and
is hit by the signal between the acquire and the release.
"""

from __future__ import annotations

import math
import os
import signal
import threading
import time

import pytest

from bench.core.engine import Interrupted, SignalGuard
from drivers import interrupts
from sims.clock import GUARD_REAL_S, SteppedClock


class _LockingTwin:
    """Each step takes `lock` by hand; at `signal_at_s` a SIGINT arrives while it is held."""

    def __init__(self, signal_at_s: float) -> None:
        self.lock = threading.Lock()
        self.signal_at_s = signal_at_s
        self.steps: list[float] = []

    def next_event_s(self, t_s: float) -> float:
        return math.floor(t_s * 10 + 1e-9) / 10 + 0.1   # a step every 0.1 s

    def advance(self, t_s: float) -> None:
        self.lock.acquire()
        self.steps.append(t_s)
        if abs(t_s - self.signal_at_s) < 1e-9:
            os.kill(os.getpid(), signal.SIGINT)
            # the handler runs at the next check of Python's eval loop: this call
            sum(range(10))
        self.lock.release()

    def settled(self, t_s: float, final: bool) -> bool:
        return True


def test_a_ctrl_c_inside_a_twins_lock_is_raised_at_the_next_step_with_the_lock_free() -> None:
    """Without the shelter the handler raises between the twin's acquire and release:
    the lock stays held and a stop sequence needing it would wait for ever."""
    clock = SteppedClock(max_step_s=1.0)
    twin = _LockingTwin(signal_at_s=0.5)
    leave = clock.join(twin)
    log: list[str] = []
    try:
        with SignalGuard(log.append) as guard, pytest.raises(Interrupted) as exc:
            clock.sleep_until(2.0)
        assert twin.lock.acquire(blocking=False), "the twin's lock was left held"
        twin.lock.release()
        assert exc.value.signame == "SIGINT"
        assert guard.pending is None             # raised once, by the clock (check()ed)
        assert not interrupts.deferred()
    finally:
        leave()
    # the step the signal hit ran to its end, and no step after it
    assert twin.steps[-1] == pytest.approx(0.5)
    assert clock.now() == pytest.approx(0.5)
    # the clock goes on for the stop sequence, and a second wait is not interrupted again
    clock.sleep(0.2)
    assert clock.now() == pytest.approx(0.7)


def test_a_ctrl_c_ends_a_settle_that_waits_for_a_twin() -> None:
    """A twin that does not settle holds a step up to GUARD_REAL_S of real time; a Ctrl-C
    meanwhile is raised at once, not after the guard (the operator waits for the stop)."""

    class _Stuck:
        def next_event_s(self, t_s: float) -> float:
            return math.inf

        def advance(self, t_s: float) -> None:
            pass

        def settled(self, t_s: float, final: bool) -> bool:
            return False

    clock = SteppedClock(max_step_s=1.0)
    leave = clock.join(_Stuck())
    timer = threading.Timer(0.2, os.kill, (os.getpid(), signal.SIGINT))
    t0 = time.monotonic()
    try:
        with SignalGuard(lambda _line: None), pytest.raises(Interrupted):
            timer.start()
            clock.sleep_until(5.0)
    finally:
        timer.cancel()
        leave()
    assert time.monotonic() - t0 < GUARD_REAL_S / 2


def test_outside_a_shelter_the_handler_raises_where_the_main_thread_is() -> None:
    """Hardware's real-time waits: the signal interrupts the wait itself, as before."""
    timer = threading.Timer(0.1, os.kill, (os.getpid(), signal.SIGINT))
    with SignalGuard(lambda _line: None), pytest.raises(Interrupted):
        timer.start()
        time.sleep(10.0)
    assert not interrupts.sheltered()
