"""Where the operator's Ctrl-C may land in the main thread.

A signal handler's exception is raised wherever the main thread happens to be. Inside a
`with lock:` block that is harmless (the block releases the lock on the way out), but
between a lock's acquire and the `with` block that owns it (inside
`threading.Condition.__enter__`, which is Python code, or in a twin's step that takes a
lock by hand) the exception leaves the lock held, and the stop sequence that needs the
same lock (the drive twin ramping the axes down) waits for it for ever.

On the co-simulation the main thread spends nearly all of a run in such code: it steps
every twin (sims.clock.SteppedClock). It does so inside `shelter()`. While sheltered,
the handler (bench.core.engine.SignalGuard) only notes the signal (`defer`), and the
shelter's owner raises it at a point where it holds no lock (`safe_point`), within one
clock step. Outside a shelter (hardware's real-time waits) nothing changes.

Bottom layer: the clock (sims) and the engine (bench) both use it, so it lives with the
drivers, like drivers/clock.py.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator


class _State:
    depth = 0                                   # the main thread's nesting of shelters
    deferred = False                            # a signal was noted inside a shelter
    deliver: Callable[[], None] | None = None   # raises the noted signal's exception


_state = _State()


def _main() -> bool:
    return threading.current_thread() is threading.main_thread()


@contextlib.contextmanager
def shelter() -> Iterator[None]:
    """A region of the main thread where a signal is noted, not raised. Other threads
    pass through unchanged (a signal handler only ever runs in the main thread)."""
    if not _main():
        yield
        return
    _state.depth += 1
    try:
        yield
    finally:
        _state.depth -= 1


def sheltered() -> bool:
    """True while the main thread is inside `shelter()` (asked by the signal handler)."""
    return _state.depth > 0


def set_delivery(deliver: Callable[[], None] | None) -> None:
    """Who raises a deferred signal's exception (the SignalGuard, while it is installed):
    a callable that raises it if the run has not received it yet."""
    _state.deliver = deliver
    _state.deferred = False


def defer() -> None:
    """Called by the signal handler instead of raising, while `sheltered()`."""
    _state.deferred = True


def deferred() -> bool:
    """A signal is waiting for the next `safe_point` (long waits end early for it)."""
    return _state.deferred


def taken() -> None:
    """The run has the signal's exception (raised by its handler's owner some other way):
    nothing is left to deliver, and waits no longer end early."""
    _state.deferred = False


def safe_point() -> None:
    """Raise a deferred signal's exception here: the caller holds no lock at this point.

    A synchronous raise from a call is safe inside any `with` block of the callers, so
    this may run at any depth of shelters; only the main thread delivers."""
    if _state.deferred and _main():
        _state.deferred = False
        deliver = _state.deliver
        if deliver is not None:
            deliver()
