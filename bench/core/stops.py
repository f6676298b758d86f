"""The one stop path: what a command opened is made safe, last opened first, once.

Every resource that must be made safe (an axis, a twin, a worker, a server, an
instrument, a raw log) registers its own stop here when it is opened, not at some later
`finally` that has to know what was opened. A command's registry runs them in reverse
order exactly once (`run`; twice is harmless, python-can's `BusABC.shutdown` is the
model); a stop that fails never skips the others (Bluesky's `finalize_wrapper`), and
each stop leaves a typed `StopOutcome`, so whether an axis may still be turning is a
field (`axis_moving`), never a phrase searched for in a message.

A registry made while another one collects (`collecting`: a session, `bench devices`,
`bench sim`) is itself registered with that one as it is made (`Stops.child`): a
`Bench`'s instruments and a `SimBench`'s twins reach the command's registry without the
procedure kind that opens them passing it along. The first cause of a failure stays
what the operator reads; the outcomes of the stops go beneath it.
"""

from __future__ import annotations

import atexit
import contextlib
import gc
import threading
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager
from contextvars import ContextVar
from dataclasses import dataclass
from types import TracebackType
from typing import Literal, Protocol, TypeVar, runtime_checkable

T = TypeVar("T")


def _freeze_at_exit() -> None:
    """At the interpreter's exit, every object into the collector's permanent generation.

    Its last collection would walk every object the command made (a run's certificate
    fonts and figures, the records' SQL, the analysis's arrays' owners) only to free
    memory the operating system takes back at exit anyway: 0.4 to 1 s of a demo run's
    wall time (issue 62; 2 s under a profiler). Nothing a command writes waits for the
    collector: every file, log and database is closed by its own stop (this module)."""
    gc.freeze()


atexit.register(_freeze_at_exit)

#: what a stop makes safe: the journal's and the tests' word for it
Resource = Literal["axis", "twin", "worker", "server", "instrument", "log", "journal",
                   "clock", "group"]


@runtime_checkable
class SaysIfMoving(Protocol):
    """An error that knows whether an axis may still be turning after it
    (drivers/axis.py AxisError: True for a drive that cannot be told to stop)."""

    axis_moving: bool


@dataclass(frozen=True, slots=True)
class StopOutcome:
    """How one stop went: `ok`, else the error's type and message; `axis_moving` when
    the failure leaves an axis that may still be turning (check the table first)."""

    what: str
    resource: Resource
    ok: bool
    error_type: str | None = None
    error: str | None = None
    axis_moving: bool = False

    @property
    def text(self) -> str:
        """The line the operator reads beneath the first cause (and the exit event's
        `later`)."""
        return self.what if self.ok else f"{self.what}: {self.error}"


def succeeded(what: str, resource: Resource) -> StopOutcome:
    return StopOutcome(what, resource, True)


def failed(what: str, resource: Resource, error: BaseException) -> StopOutcome:
    """The outcome of a stop that raised `error`."""
    moving = isinstance(error, SaysIfMoving) and error.axis_moving is True
    return StopOutcome(what, resource, False, type(error).__name__,
                       str(error) or type(error).__name__, moving)


def attempt(what: str, stop: Callable[[], T], resource: Resource) -> StopOutcome:
    """Run one stop; its outcome, never its exception (the others must still run)."""
    try:
        stop()
    except Exception as e:  # noqa: BLE001 - an outcome, beneath the first cause
        return failed(what, resource, e)
    return succeeded(what, resource)


@dataclass(frozen=True, slots=True)
class _Entry:
    what: str
    resource: Resource
    stop: Callable[[], None] | None
    child: Stops | None = None


_collecting: ContextVar[Stops | None] = ContextVar("bench_stops", default=None)


def register(what: str, stop: Callable[[], T], resource: Resource) -> None:
    """Register `stop` with the registry collecting now (a command's), for a resource
    made deep inside a kind's code (the analysis's hashing threads). With none collecting
    (a test, a library use), the resource's owner's own cleanup is the only one."""
    current = _collecting.get()
    if current is not None:
        current.add(what, stop, resource)


class Stops:
    """A thread-safe registry of stops, run last registered first, each once."""

    def __init__(self) -> None:
        self._lock = threading.RLock()
        self._entries: list[_Entry] = []
        self._outcomes: list[StopOutcome] = []
        self._unreported: list[StopOutcome] = []  # not yet handed to a parent registry

    @classmethod
    def child(cls, what: str, resource: Resource = "group") -> Stops:
        """A new registry, registered with the one collecting now (if any) as it is made:
        its stops run there, in their place, when that one runs."""
        made = cls()
        parent = _collecting.get()
        if parent is not None:
            parent.adopt(made, what, resource)
        return made

    @contextlib.contextmanager
    def collecting(self) -> Iterator[Stops]:
        """Registries made inside (`child`) register with this one."""
        token = _collecting.set(self)
        try:
            yield self
        finally:
            _collecting.reset(token)

    # -- registering ---------------------------------------------------------------------
    def add(self, what: str, stop: Callable[[], T], resource: Resource) -> None:
        """Register `stop` (it must be safe to call twice: a resource may be closed early
        by its owner)."""
        def run() -> None:
            stop()      # run for its effect: what it returns (a close's count) is dropped
        with self._lock:
            self._entries.append(_Entry(what, resource, run))

    def enter(self, cm: AbstractContextManager[T], what: str, resource: Resource) -> T:
        """Enter `cm` and register its exit."""
        obj = cm.__enter__()
        self.add(what, lambda: cm.__exit__(None, None, None), resource)
        return obj

    def adopt(self, child: Stops, what: str, resource: Resource = "group") -> None:
        """Run `child`'s stops here, in the place of this registration."""
        with self._lock:
            self._entries.append(_Entry(what, resource, None, child))

    def record(self, *outcomes: StopOutcome) -> None:
        """Outcomes of stops run outside the registry (the engine's safe stop of every
        axis at a fault, before anything is closed)."""
        with self._lock:
            self._outcomes += outcomes
            self._unreported += outcomes

    # -- running -------------------------------------------------------------------------
    def run(self) -> tuple[StopOutcome, ...]:
        """Run every registered stop, last registered first, each once; returns the
        outcomes not yet returned (those recorded since, and of earlier runs). A stop
        that raises a BaseException (SystemExit) does not skip the others: it is raised
        once they have run."""
        pending = self._run_entries()
        out = self._drain()
        if pending is not None:
            raise pending
        return out

    def _run_entries(self) -> BaseException | None:
        pending: BaseException | None = None
        while True:
            with self._lock:
                if not self._entries:
                    return pending
                entry = self._entries.pop()
            if entry.child is not None:       # its outcomes here, whatever it raised
                raised = entry.child._run_entries()
                self.record(*entry.child._drain())
                pending = pending or raised
                continue
            assert entry.stop is not None
            try:
                self.record(attempt(entry.what, entry.stop, entry.resource))
            except BaseException as e:  # noqa: BLE001 - the rest still run; raised after
                self.record(failed(entry.what, entry.resource, e))
                pending = pending or e

    def _drain(self) -> tuple[StopOutcome, ...]:
        with self._lock:
            out, self._unreported = tuple(self._unreported), []
        return out

    @property
    def outcomes(self) -> tuple[StopOutcome, ...]:
        """Every outcome so far, in the order the stops ran."""
        with self._lock:
            return tuple(self._outcomes)

    @property
    def failures(self) -> tuple[StopOutcome, ...]:
        return tuple(o for o in self.outcomes if not o.ok)

    @property
    def axis_moving(self) -> bool:
        """A stop failed in a way that may leave an axis turning."""
        return any(o.axis_moving for o in self.outcomes)

    def __enter__(self) -> Stops:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.run()
