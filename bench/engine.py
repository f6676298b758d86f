"""The engine: executes a plan's steps on a bench, and stops the table whatever happens.

The engine is the same for every procedure kind and for real or simulated instruments:
the kind executes each step; the engine journals it, reports progress, and on any
exception, driver fault, Ctrl-C or SIGTERM stops every axis (ramp to zero, then
disable) before anything else. A second Ctrl-C while stopping does not skip the stop.
"""

from __future__ import annotations

import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from types import FrameType
from typing import IO, Any, Protocol

from bench.config import Config
from bench.journal import RunDir
from bench.plan import Plan, Step, format_duration
from drivers.clock import Clock


class Abort(Exception):
    """The operator (Ctrl-C, SIGTERM) or a fault ended the run."""


class Interrupted(Abort):
    def __init__(self, signame: str) -> None:
        super().__init__(f"interrupted by {signame}")
        self.signame = signame


class StoppableBench(Protocol):
    """What the engine needs of the instruments: a safe stop and a close."""

    def safe_stop(self, log: Callable[[str], None]) -> None: ...

    def close(self) -> None: ...


class SignalGuard:
    """SIGINT/SIGTERM become `Interrupted` in the main thread, except while stopping."""

    def __init__(self, log: Callable[[str], None]) -> None:
        self.stopping = False
        self.count = 0
        self._log = log
        self._old: dict[int, Any] = {}

    def _handler(self, signum: int, frame: FrameType | None) -> None:
        self.count += 1
        name = signal.Signals(signum).name
        if self.stopping:
            self._log(f"{name} received: the axes are being stopped first; please wait")
            return
        self.stopping = True
        raise Interrupted(name)

    def __enter__(self) -> SignalGuard:
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, self._handler)
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, old in self._old.items():
            # once interrupted, more signals only cut short the last lines of output
            signal.signal(sig, signal.SIG_IGN if self.count else old)


class Progress:
    """Progress lines: rewritten in place on a terminal, plain lines otherwise."""

    def __init__(self, stream: IO[str] | None = None, min_interval_s: float = 2.0) -> None:
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.min_interval_s = min_interval_s
        self._last_detail = 0.0
        self._open_line = False

    def line(self, text: str) -> None:
        if self._open_line:
            self.stream.write("\n")
            self._open_line = False
        self.stream.write(text + "\n")
        self.stream.flush()

    def detail(self, text: str, force: bool = False) -> None:
        """A frequent update (turn counter): in place on a tty, throttled otherwise."""
        now = time.monotonic()
        if self.tty:
            self.stream.write("\r\033[K" + text)
            self.stream.flush()
            self._open_line = True
        elif force or now - self._last_detail >= self.min_interval_s:
            self.line(text)
            self._last_detail = now


@dataclass
class RunContext:
    """What a procedure kind's step needs: config, clock, instruments, journal, progress."""

    cfg: Config
    clock: Clock
    bench: Any
    run: RunDir
    progress: Progress
    yes: bool = False
    state: dict[str, Any] = field(default_factory=dict)
    eta_s: Callable[[], float] = lambda: 0.0

    def prompt(self, text: str) -> None:
        """An operator prompt; --yes answers it (unattended runs, CI)."""
        self.run.event("prompt", text=text, answered="yes" if self.yes else "operator")
        if self.yes:
            self.progress.line(f"PROMPT  {text}  [--yes]")
            return
        if not sys.stdin.isatty():
            raise Abort(f"operator prompt needs an answer and stdin is not a terminal "
                        f"(use --yes for unattended runs): {text}")
        answer = input(f"{text}\nPress Enter when done (or type 'abort'): ")
        if answer.strip().lower() in ("abort", "a", "no", "n"):
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
        ctx.run.event("plan", steps=len(steps), estimate_s=plan.total_s,
                      step_estimates_s=[s.estimate_s for s in steps])
        try:
            for i, step in enumerate(steps):
                ctx.eta_s = (lambda i=i: remaining[i])
                eta_real = remaining[i] / ctx.clock.speed
                ctx.progress.line(
                    f"[{i + 1}/{len(steps)}] {step.axis or '':<6} {step.action:<9} "
                    f"{step.describe}   (bench time left {format_duration(remaining[i])}"
                    + (f", about {format_duration(eta_real)} here)" if ctx.clock.speed != 1
                       else ")"))
                ctx.run.event("step_start", index=i, action=step.action, axis=step.axis,
                              unit=step.unit, describe=step.describe)
                self.execute(step, ctx)
                ctx.run.event("step_done", index=i, action=step.action, unit=step.unit)
                if step.unit and last_of_unit[step.unit] == i:
                    ctx.run.event("unit_done", unit=step.unit)
        except BaseException as exc:  # noqa: BLE001 - every failure must stop the table
            guard.stopping = True
            reason = str(exc) or type(exc).__name__
            ctx.progress.line(f"ABORT: {reason}")
            later: list[str] = []
            try:
                ctx.run.event("abort", reason=reason, error=type(exc).__name__,
                              traceback=traceback.format_exc(limit=8))
            except Exception as e:  # noqa: BLE001 - the stop comes first, whatever the disk
                later.append(f"the abort could not be journaled: {e}")
            later += self.safe_stop()
            out = exc if isinstance(exc, Abort) else Abort(reason)
            for note in later:
                out.add_note(f"also, while stopping: {note}")
            if out is exc:
                raise
            raise out from exc

    def safe_stop(self) -> list[str]:
        """Stop every axis; returns what went wrong (never raises: it runs after a fault)."""
        ctx = self.ctx
        ctx.progress.line("Stopping every axis (ramp to zero, then disable)...")
        errors: list[str] = []
        try:
            ctx.bench.safe_stop(ctx.progress.line)
            ok, error = True, None
        except BaseException as e:  # noqa: BLE001
            ok, error = False, repr(e)
            errors.append(f"safe stop: {e}")
            ctx.progress.line(f"SAFE STOP FAILED: {e!r}: check the table by hand")
        try:
            ctx.run.event("safe_stop", ok=ok, **({"error": error} if error else {}))
        except Exception as e:  # noqa: BLE001
            errors.append(f"the safe stop could not be journaled: {e}")
        return errors
