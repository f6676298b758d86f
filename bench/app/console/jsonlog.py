"""The console as JSON lines, for a program watching the run (`bench run --log-json`).

One object per line: {"utc", "event", ...}. Events: plan, step (with bench_left_s,
wall_left_s, speed), progress (throttled), reading, message, warning, prompt, summary,
end, and log (a library's or a twin's logged warning: Python would print it as plain text,
and a log collector would choke on that one line). Numbers are plain floats in SI-like units named in the key, as in result.json.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable, Sequence
from typing import IO

from bench.app.console.figures import figure_text, figures_text
from bench.app.console.plain import PlainConsole
from bench.app.console.report import Summary
from bench.core.journal import utc_now
from bench.core.plan import Step
from bench.core.progress import Figure


class _LogLines(logging.Handler):
    """Warnings logged anywhere in the process, as the console's `log` objects."""

    def __init__(self, console: JsonConsole) -> None:
        super().__init__(logging.WARNING)
        self.console = console

    def emit(self, record: logging.LogRecord) -> None:
        try:
            self.console.emit("log", level=record.levelname, logger=record.name,
                              text=record.getMessage())
        except Exception:  # noqa: BLE001 - logging's own rule: a handler never raises
            self.handleError(record)


class JsonConsole(PlainConsole):
    def __init__(self, stream: IO[str] | None = None, min_interval_s: float = 2.0,
                 out: IO[str] | None = None) -> None:
        super().__init__(stream, min_interval_s, out)
        root = logging.getLogger()
        for h in [h for h in root.handlers if isinstance(h, _LogLines)]:
            root.removeHandler(h)       # one console of the process at a time: the newest
        root.addHandler(_LogLines(self))

    def emit(self, event: str, **fields: object) -> None:
        rec = {"utc": utc_now(), "event": event, **fields}
        self.stream.write(json.dumps(rec, ensure_ascii=False, allow_nan=False, default=str)
                          + "\n")
        self.stream.flush()

    def begin(self, steps: Sequence[Step], clock_now: Callable[[], float],
              backlog_s: Callable[[], float] | None = None) -> None:
        super().begin(steps, clock_now, backlog_s)
        self.emit("plan", steps=len(steps), bench_estimate_s=sum(s.estimate_s for s in steps))

    def show_step(self, index: int) -> None:
        step = self.steps[index]
        eta = self.eta()
        self.emit("step", index=index + 1, steps=len(self.steps), action=step.action,
                  axis=step.axis, describe=step.describe, estimate_s=step.estimate_s,
                  bench_left_s=eta.bench_left_s if eta else None,
                  wall_left_s=eta.wall_left_s if eta else None,
                  speed=eta.speed if eta else None)

    def step_done(self, index: int) -> None:
        super().step_done(index)
        self.emit("step_done", index=index + 1)

    def end(self) -> None:
        self.emit("end")

    def line(self, text: str) -> None:
        self.emit("message", text=text.strip())

    def warn(self, text: str) -> None:
        self.emit("warning", text=text.strip())

    def detail(self, text: str, force: bool = False) -> None:
        now = time.monotonic()
        if force or now - self._last_detail >= self.min_interval_s:
            self.emit("progress", text=text.strip())
            self._last_detail = now

    def advance(self, done: float, total: float, text: str) -> None:
        now = time.monotonic()
        if now - self._last_detail >= self.min_interval_s:
            self.emit("progress", done=done, total=total, text=text)
            self._last_detail = now

    def reading(self, name: str, label: str, *figures: Figure) -> None:
        self.emit("reading", name=name, label=label, text=figures_text(figures),
                  figures=[_figure(f) for f in figures])

    def result(self, label: str, *figures: Figure) -> None:
        self.emit("result", label=label, text=figures_text(figures),
                  figures=[_figure(f) for f in figures])

    def ask(self, text: str) -> str:
        self.emit("prompt", text=text)
        return self.read_answer()

    def summary(self, summary: Summary) -> None:
        """The certificate's figures as text cells (the numbers as the certificate prints
        them; result.json holds them unrounded)."""
        self.emit("summary", verdict=summary.verdict, statement=summary.statement,
                  tables=[{"title": t.title, "header": list(t.header),
                           "rows": [list(r) for r in t.rows]} for t in summary.tables],
                  fields=dict(summary.fields))


def _figure(f: Figure) -> dict[str, str | float | None]:
    """The number unrounded (as in result.json) and as the certificate would print it."""
    return {"name": f.name, "value": f.value, "u": f.u, "unit": f.unit, "text": figure_text(f)}
