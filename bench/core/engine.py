"""The engine: executes a plan's steps on a bench, and stops the table whatever happens.

The engine is the same for every procedure kind and for real or simulated instruments:
the kind executes each step; the engine journals it, reports progress, and on any
exception, driver fault, Ctrl-C or SIGTERM stops every axis (ramp to zero, then
disable) before anything else. A second Ctrl-C while stopping does not skip the stop.
"""

from __future__ import annotations

import functools
import importlib
import os
import select
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass, field
from types import FrameType, TracebackType
from typing import TYPE_CHECKING, Protocol, TypeVar, TypeVarTuple

from bench.core import events as ev
from bench.core.config import Config
from bench.core.journal import RunDir, utc_now
from bench.core.plan import Plan, Step
from bench.core.progress import Progress
from bench.core.stops import StopOutcome, Stops, attempt, failed
from drivers import interrupts
from drivers.clock import Clock

if TYPE_CHECKING:
    # multiprocessing is imported when the worker starts: a kind imports this module,
    # and `bench validate` loads the kind
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing.context import BaseContext

    from bench.core.instruments import Bench


R = TypeVar("R")
Ts = TypeVarTuple("Ts")

#: what `signal.signal` takes and returns: a handler, SIG_DFL/SIG_IGN, or None
SignalHandler = Callable[[int, FrameType | None], None] | int | signal.Handlers | None


class Abort(Exception):
    """The operator (Ctrl-C, SIGTERM) or a fault ended the run."""


class Interrupted(BaseException):
    """The operator's Ctrl-C or a SIGTERM, raised in the main thread wherever it is.

    A BaseException, as KeyboardInterrupt is, so that no `except Exception` the main
    thread runs through swallows it: on the co-simulation clock that includes the twins'
    steps (a drive twin's tick logs and survives its own failures), where a Ctrl-C was
    once logged as a failed tick and the run went on to exit 0. The engine turns it into
    an Abort with the same message once the axes are stopped."""

    def __init__(self, signame: str) -> None:
        super().__init__(f"interrupted by {signame}")
        self.signame = signame


class StoppableBench(Protocol):
    """What the engine needs of the instruments: a safe stop of every axis (one outcome
    per axis, raises none: bench/core/instruments.py Bench)."""

    def safe_stop(self, log: Callable[[str], None]) -> tuple[StopOutcome, ...]: ...


class SignalGuard:
    """SIGINT/SIGTERM become `Interrupted` in the main thread, except while stopping.

    A handler's exception is raised wherever the main thread happens to be, and where that
    is a garbage-collection callback or a `__del__`, Python prints "Exception ignored" and
    goes on: a loaded suite run saw a Ctrl-C during the certificate's writing land in
    SQLAlchemy's weakref callback, and the run exited 0 with every output written. So the
    exception is also kept as `pending` until the run receives it (`received`), and
    `check` raises it again where the run can take it: the engine's step boundaries, the
    end of the measurement, the end of the writing. A signal that comes while one is still
    pending raises again, instead of "the axes are being stopped first".

    Inside a co-simulation step (drivers/interrupts.py `shelter`) the main thread may hold
    a twin's lock, and an exception landing between its acquire and its `with` block
    would leave it held for the stop sequence to wait on for ever: there the signal is
    only noted, and the clock raises it at its next safe point, within one step.
    """

    def __init__(self, log: Callable[[str], None]) -> None:
        self.stopping = False
        #: the axes are stopped and the outputs are being written: a signal now ends the
        #: writing (KeyboardInterrupt), since nothing is left to protect but derived files
        self.writing = False
        self.count = 0
        #: the exception of a signal the run has not yet received (see the class's note)
        self.pending: Interrupted | KeyboardInterrupt | None = None
        self._log = log
        self._old: dict[int, SignalHandler] = {}

    def _handler(self, signum: int, frame: FrameType | None) -> None:
        self.count += 1
        name = signal.Signals(signum).name
        if self.writing:
            self.writing = False
            self.pending = KeyboardInterrupt(name)
        elif self.stopping and self.pending is None:
            self._log(f"{name} received: the axes are being stopped first; please wait")
            return
        else:
            self.stopping = True
            self.pending = Interrupted(name)
        if interrupts.sheltered():
            # the main thread may be inside a lock (a co-simulation step): raised at the
            # clock's next safe point instead, within one step (drivers/interrupts.py)
            interrupts.defer()
            return
        raise KeyboardInterrupt(name) if isinstance(self.pending, KeyboardInterrupt) \
            else Interrupted(name)

    def received(self) -> None:
        """The run has taken the signal's exception (or is stopping for another cause)."""
        self.pending = None
        interrupts.taken()

    def check(self) -> None:
        """Raise a signal's exception again if it was lost where it landed."""
        lost, self.pending = self.pending, None
        interrupts.taken()
        if isinstance(lost, Interrupted):
            raise Interrupted(lost.signame)
        if lost is not None:
            raise KeyboardInterrupt(*lost.args)

    def __enter__(self) -> SignalGuard:
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, self._handler)
            interrupts.set_delivery(self.check)
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        for sig, old in self._old.items():
            # once interrupted, more signals only cut short the last lines of output
            signal.signal(sig, signal.SIG_IGN if self.count else old)
        if self._old:
            interrupts.set_delivery(None)


#: how much lower the analysis worker's CPU priority is than the bench's (nice steps)
WORKER_NICE = 10


#: how often the analysis worker looks whether the bench process lives, without a pidfd (s)
PARENT_WATCH_S = 0.5


#: a kind's module may name, in this attribute, the modules its worker jobs need that it
#: does not import itself (it imports its analysis where it uses it, so that `bench
#: validate` loads none of it); the worker imports them at its start. A kind that names
#: none has no worker started with its run: one starts at its first job, if it has any
WORKER_PRELOAD = "WORKER_PRELOAD"

#: the fork server's start (`_worker_context`): the modules it imported and the bench's
#: environment it started with; None until this process first starts a worker
_server: tuple[tuple[str, ...], dict[str, str]] | None = None
_server_lock = threading.Lock()


def _worker_modules(module: str | None) -> tuple[str, ...]:
    """What `_preload(module)` imports, in its order (the kind's module is this process's
    already: its steps run here)."""
    if not module:
        return ()
    names: tuple[str, ...] = tuple(getattr(importlib.import_module(module), WORKER_PRELOAD,
                                           ()))
    return (module, *names)


def _worker_context(modules: tuple[str, ...]) -> tuple[BaseContext, tuple[str, ...],
                                                       dict[str, str]]:
    """How analysis workers start, with the modules and environment they start with.

    "forkserver": a server process, started once per bench process by a spawn (a fresh
    interpreter, never a fork of a process with CAN threads), imports `modules` once
    (numpy, scipy, the kind's analysis: 1.5 to 2.5 s of CPU) and forks each session's
    worker with them imported, in milliseconds (issue 62: the suite makes more than 100
    runs in its processes, each with a worker). It is started here, without waiting: it
    imports while the run's first steps are made. It ends when every process that can
    ask it for a worker has (the bench and its workers). "spawn" (a worker that imports
    what its jobs need itself) before a kind has named its modules (a bare `submit`: the
    server would start without them) and where there is no fork server.
    """
    global _server
    import multiprocessing
    from multiprocessing import forkserver

    with _server_lock:
        if _server is None:
            if not modules or "forkserver" not in multiprocessing.get_all_start_methods():
                return multiprocessing.get_context("spawn"), (), dict(os.environ)
            forkserver.set_forkserver_preload(["__main__", *modules])
            _server = (modules, dict(os.environ))
        forkserver.ensure_running()
        return multiprocessing.get_context("forkserver"), *_server


def _preload(module: str | None) -> None:
    """In the worker: import what its jobs will need (AnalysisWorker.start)."""
    if module:
        loaded = importlib.import_module(module)
        for name in getattr(loaded, WORKER_PRELOAD, ()):
            importlib.import_module(name)


def _worker_init(bench_pid: int, bench_nice: int, environ: dict[str, str],
                 server_environ: dict[str, str]) -> None:
    """In the worker: the bench's environment, a lower priority, and an end when the bench
    process ends, however it ends.

    The worker is forked from the fork server (`_worker_context`), whose environment is the
    bench's when the server started: a spawned worker had the bench's as of its session
    (a test's monkeypatch.setenv, say). It gets that again, with what the server's own
    imports set on top (bench/analysis/blas.py's OPENBLAS_NUM_THREADS): as a spawned
    worker had it after the same imports.
    """
    # Ctrl-C at the terminal reaches the whole foreground process group, this worker too:
    # the bench handles it (stops the axes, then ends this worker); here it printed a
    # KeyboardInterrupt traceback above the bench's "ABORT: interrupted by SIGINT" and
    # broke the job the bench was waiting for
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    set_by_imports = {k: v for k, v in os.environ.items() if server_environ.get(k) != v}
    os.environ.clear()
    os.environ.update(environ)
    os.environ.update(set_by_imports)
    # the priority the bench's plus WORKER_NICE, so on a busy machine the acquisition
    # threads (FOG reader, heartbeat, twins) get the CPU first and the analysis waits;
    # counted from the bench's now, not from the server's (forked from it at its start)
    target = min(bench_nice + WORKER_NICE, 19)
    lowered = os.nice(max(target - os.nice(0), 0))
    # os.nice lowers only this thread; BLAS threads started before it (in a spawned
    # worker, at numpy's import) ran on at the bench's priority, one of them spinning
    # between the pair analyses' matrix products (perf on the paper ladder, 27 Nov 2026:
    # 1.4 % of both cores at nice 0). Their number is one (bench/analysis/blas.py)
    _lower_every_thread(lowered)
    threading.Thread(target=_watch_bench, args=(bench_pid,), name="bench-watch",
                     daemon=True).start()


def _watch_bench(bench_pid: int) -> None:
    """In the worker: its end when the bench process ends.

    A SIGKILLed bench runs no cleanup: its worker, blocked on the job queue, would live on,
    holding the raw files and the bench's stdout/stderr open (so a `bench run ... | tee
    log` never ends). Its parent is the fork server, which ends only when every process
    holding its alive pipe has (the bench and each worker), so the worker watches the
    bench itself: a pidfd is readable once that process has ended (Linux 5.3); elsewhere,
    a look every PARENT_WATCH_S (a bench not yet reaped by its parent counts as alive).
    """
    try:
        pidfd = os.pidfd_open(bench_pid) if hasattr(os, "pidfd_open") else None
    except ProcessLookupError:
        os._exit(1)              # ended before the worker started
    except OSError:
        pidfd = None             # a kernel without pidfds
    if pidfd is not None:
        select.select([pidfd], [], [])
    else:
        try:
            while True:          # gone, or its pid another user's: the bench has ended
                os.kill(bench_pid, 0)
                time.sleep(PARENT_WATCH_S)
        except OSError:
            pass
    os._exit(1)  # the bench is gone: nobody will read a result; no cleanup to run


def _lower_every_thread(nice: int) -> None:
    """Every thread of this process at least `nice` (Linux's priorities are per thread;
    elsewhere os.nice already covers the process)."""
    tasks = "/proc/self/task"
    if not os.path.isdir(tasks):
        return
    for tid in os.listdir(tasks):
        try:
            if os.getpriority(os.PRIO_PROCESS, int(tid)) < nice:
                os.setpriority(os.PRIO_PROCESS, int(tid), nice)
        except (ProcessLookupError, PermissionError):
            pass  # a thread that ended meanwhile; or a limit this user may not change


class AnalysisWorker:
    """Heavy analysis in a process of its own, so it cannot starve acquisition.

    The FOG's serial reader, the CAN heartbeat and the twins are threads of the bench
    process: a pair's analysis there (seconds of numpy at 36 M samples) would hold the
    interpreter while frames and heartbeats are due. In a worker process it runs on the
    other core, at a lower priority (WORKER_NICE), and the run goes on acquiring the next
    pair meanwhile. `submit` never
    blocks; `on_done(result, error)` runs in a thread of this process when it is done.
    The worker is a fork of a fork server (`_worker_context`: never a fork of a process
    with CAN threads) made at the first job, and kept for the session, so it keeps its
    state between jobs.
    """

    def __init__(self) -> None:
        self._pool: ProcessPoolExecutor | None = None
        #: monotonic time of each submitted job not yet done, by its number
        self._submitted: dict[int, float] = {}
        self._jobs = 0                                  # jobs submitted so far
        self._took_s: list[float] = []                  # wall time of each finished job
        self._lock = threading.Lock()
        self._failed: list[str] = []  # what an on_done raised: reported by close()
        #: jobs whose on_done has not yet returned (wait_reported waits for 0)
        self._unreported = 0
        self._reported = threading.Condition(self._lock)

    def start(self, preload: str | None = None) -> None:
        """Get the worker ready now (its imports take seconds), so the first pair's look
        does not pay for them; `preload` names the kind's module, whose WORKER_PRELOAD
        the worker imports. Safe to call twice.

        The first worker of a process starts the fork server (`_worker_context`), which
        imports them; the worker is forked at the first job. A later session of another
        kind forks its worker now, to import its own there."""
        modules = _worker_modules(preload)
        if self._pool is not None or (preload and modules == (preload,)):
            return     # a kind that names no modules for its worker: none started early
        from concurrent.futures import ProcessPoolExecutor
        context, imported, server_environ = _worker_context(modules)
        self._pool = ProcessPoolExecutor(
            max_workers=1, mp_context=context, initializer=_worker_init,
            initargs=(os.getpid(), os.nice(0), dict(os.environ), server_environ))
        if not set(modules) <= set(imported):
            self._pool.submit(_preload, preload)   # starts it; the initializer runs there

    def submit(self, fn: Callable[[*Ts], R], *args: *Ts,
               on_done: Callable[[R | None, BaseException | None], None]) -> None:
        """Run `fn(*args)` in the worker; `on_done(result, None)` or `on_done(None, error)`
        in a thread of this process when it is done (typed as concurrent.futures types its
        Future[R]: each kind's jobs return their own result type)."""
        self.start()
        assert self._pool is not None
        fut = self._pool.submit(fn, *args)
        with self._lock:
            self._jobs += 1
            job = self._jobs
            self._submitted[job] = time.monotonic()
            self._unreported += 1

        def done(f: Future[R]) -> None:
            try:
                report(f)
            finally:
                with self._lock:
                    self._unreported -= 1
                    self._reported.notify_all()

        def report(f: Future[R]) -> None:
            with self._lock:
                t0 = self._submitted.pop(job, None)
                if t0 is not None and not f.cancelled():
                    self._took_s.append(time.monotonic() - t0)
            if f.cancelled():
                return
            err = f.exception()
            try:
                on_done(None if err else f.result(), err)
            except Exception as e:  # noqa: BLE001 - e.g. a full disk while journaling it
                # raised here it would be printed by concurrent.futures as a traceback;
                # the session reports it with the rest instead (close())
                with self._lock:
                    self._failed.append(f"a pair's first look could not be reported: {e}")
        fut.add_done_callback(done)

    def wait_reported(self, at_most: int = 0) -> None:
        """Until no more than `at_most` submitted jobs are still to be reported (done,
        and their on_done returned: the result printed and journaled). A future is done
        before its callbacks have run, so waiting on the futures alone may let the last
        pair's line follow the run's end."""
        with self._lock:
            self._reported.wait_for(lambda: self._unreported <= at_most)

    def backlog_s(self) -> float:
        """Wall seconds the jobs not yet done should still take (one at a time, each as
        long as those done took on average); 0 when none is pending or none has finished
        yet to measure by. The run's end waits for them: the console's ETA counts it."""
        with self._lock:
            if not self._submitted or not self._took_s:
                return 0.0
            mean = sum(self._took_s) / len(self._took_s)
            oldest = min(self._submitted.values())
            return max(mean * len(self._submitted) - (time.monotonic() - oldest), 0.0)

    def close(self, wait: bool = True) -> list[str]:
        """Let submitted jobs finish (wait=True) or drop those not started, then stop;
        returns what went wrong reporting their results (safe to call twice)."""
        if self._pool is not None:
            if wait:
                # every job's on_done returned (so every job done, or cancelled): their
                # results printed before "completed"
                self.wait_reported()
            # every job done and reported: the worker's exit (its interpreter's teardown,
            # 0.1 to 1 s at nice 10 on a busy machine) is not waited for; the executor's
            # own thread reaps it, and Python joins that thread at exit
            self._pool.shutdown(wait=not wait, cancel_futures=not wait)
            self._pool = None
        with self._lock:
            problems, self._failed = self._failed, []
        return problems

    def stop(self) -> None:
        """The worker's stop (the session's registry): jobs not started are dropped;
        raises what went wrong reporting the results. Safe to call twice."""
        problems = self.close(wait=False)
        if problems:
            raise RuntimeError("; ".join(problems))


@dataclass
class RunContext:
    """What a procedure kind's step needs: config, clock, instruments, journal, console."""

    cfg: Config
    clock: Clock
    bench: Bench
    run: RunDir
    progress: Progress
    yes: bool = False
    eta_s: Callable[[], float] = lambda: 0.0
    worker: AnalysisWorker = field(default_factory=AnalysisWorker)
    #: the session's stop registry: the worker registers its stop there when started,
    #: the engine records its safe stop's outcomes (bench/core/stops.py)
    stops: Stops = field(default_factory=Stops)

    def prompt(self, text: str) -> None:
        """An operator prompt: a person answers it on a terminal, or --yes answers it for
        an unattended run. Either way the answer, who gave it and when are journaled (the
        certificate lists them)."""
        asked = utc_now()
        if self.yes:
            self.run.write(ev.Prompted(text=text, answered="yes", answered_by="--yes",
                                       answer="", asked_utc=asked, answered_utc=asked))
            self.progress.warn(f"PROMPT  {text}  [answered by --yes]")
            return
        if not sys.stdin.isatty():
            raise Abort(f"operator prompt needs an answer and stdin is not a terminal "
                        f"(use --yes for unattended runs): {text}")
        answer = self.progress.ask(f"PROMPT  {text}").strip()
        aborted = answer.lower() in ("abort", "a", "no", "n")
        self.run.write(ev.Prompted(text=text, answered="abort" if aborted else "yes",
                                   answered_by="operator", answer=answer, asked_utc=asked,
                                   answered_utc=utc_now()))
        if aborted:
            raise Abort("the operator aborted at a prompt")


StepRunner = Callable[[Step, RunContext], None]


class Engine:
    """Runs a plan, journals every step, and stops safely on anything."""

    def __init__(self, ctx: RunContext, execute: StepRunner) -> None:
        self.ctx = ctx
        self.execute = execute

    def run(self, plan: Plan, guard: SignalGuard) -> None:
        """Execute every step; raises Abort (after the safe stop) on any failure."""
        ctx = self.ctx
        steps = plan.steps
        remaining = [sum(s.estimate_s for s in steps[i:]) for i in range(len(steps))]
        last_of_unit = {s.unit: i for i, s in enumerate(steps) if s.unit}
        ctx.run.write(ev.Planned(steps=len(steps), estimate_s=plan.total_s,
                                 step_estimates_s=[s.estimate_s for s in steps]))
        ctx.progress.begin(steps, ctx.clock.now, ctx.worker.backlog_s)
        # the worker started, and the kind's modules imported there, while the first
        # steps run: the first pair's look does not wait seconds for an interpreter
        # (its result was shown 19 steps late). Not a bound on the lag: waiting for each
        # look in a co-simulation cost the paper ladder 148 s against 120 s (one pair
        # outstanding: 151 s; two: 130 s), where the analysis outruns nothing.
        ctx.worker.start(preload=getattr(self.execute, "__module__", None))
        ctx.stops.add("the analysis worker", ctx.worker.stop, "worker")
        try:
            for i, step in enumerate(steps):
                guard.check()
                ctx.eta_s = functools.partial(remaining.__getitem__, i)
                ctx.progress.step(i)
                ctx.run.write(ev.StepStarted(index=i, action=step.action, axis=step.axis,
                                             unit=step.unit, describe=step.describe))
                self.execute(step, ctx)
                ctx.progress.step_done(i)
                ctx.run.write(ev.StepDone(index=i, action=step.action, unit=step.unit))
                if step.unit and last_of_unit[step.unit] == i:
                    ctx.run.write(ev.UnitDone(unit=step.unit))
            # the last pair's first look, before "completed"
            for problem in ctx.worker.close(wait=True):
                ctx.progress.warn(f"WARNING: {problem}")
            guard.check()
            ctx.progress.end()
        except BaseException as exc:  # noqa: BLE001 - every failure must stop the table
            guard.stopping = True
            guard.received()
            ctx.progress.end()
            reason = str(exc) or type(exc).__name__
            ctx.progress.warn(f"ABORT: {reason}")
            error, trace = type(exc).__name__, traceback.format_exc(limit=8)
            ctx.stops.record(attempt(
                "journaling the abort event", lambda: ctx.run.write(
                    ev.Aborted(reason=reason, error=error, traceback=trace)), "journal"))
            self.safe_stop()
            # jobs not started are dropped now (an Engine may run without a session);
            # its registered stop, next, finds it closed
            dropped = attempt("the analysis worker", ctx.worker.stop, "worker")
            if not dropped.ok:
                ctx.stops.record(dropped)
            if isinstance(exc, Abort):
                raise
            raise Abort(reason) from exc

    def safe_stop(self) -> None:
        """Stop every axis, first of all after a fault; its outcomes go to the session's
        registry (never raises: it runs after a fault)."""
        ctx = self.ctx
        ctx.progress.line("Stopping every axis (ramp to zero, then disable)...")
        try:
            outcomes = ctx.bench.safe_stop(ctx.progress.line)
        except BaseException as e:  # noqa: BLE001 - a bench that is not ours to trust
            outcomes = (failed("safe stop", "axis", e),)
        ctx.stops.record(*outcomes)
        errors = [o.text for o in outcomes if not o.ok]
        if errors:
            ctx.progress.warn(f"SAFE STOP FAILED: {'; '.join(errors)}: check the table by hand")
        error = repr(RuntimeError("; ".join(errors))) if errors else None
        ctx.stops.record(attempt("journaling the safe_stop event",
                                 lambda: ctx.run.write(ev.SafeStopped(ok=not errors,
                                                                      error=error)),
                                 "journal"))
