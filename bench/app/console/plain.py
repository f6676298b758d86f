"""The console as plain lines: one per step, for a log file, CI, or a pipe.

This is also the interface every console offers the engine and the procedures; the live
terminal display and the JSON log override how each call is shown, never what is said.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable, Sequence
from typing import IO

from rich.console import Console
from rich.text import Text

from bench.app.console.figures import figures_text
from bench.app.console.report import Summary, print_summary
from bench.app.console.timeline import Eta, Timeline
from bench.core.plan import Step
from bench.core.progress import Figure

ANSWER_PROMPT = "Press Enter when done (or type 'abort'): "


class PlainConsole:
    """Plain lines on a stream (stderr by default): one line per step, results, faults.

    Frequent updates (`detail`, `advance`) are throttled to one line every
    `min_interval_s`, so a day-long run leaves a log a person can read.
    """

    interactive = False  # the live terminal display answers prompts in place

    def __init__(self, stream: IO[str] | None = None, min_interval_s: float = 2.0,
                 out: IO[str] | None = None) -> None:
        self.stream = stream or sys.stderr
        self.out = out or sys.stdout   # the summary and the run directory go here
        self.min_interval_s = min_interval_s
        self._last_detail = 0.0
        self.timeline: Timeline | None = None
        self.steps: Sequence[Step] = ()

    # -- what the engine reports ------------------------------------------------------
    def begin(self, steps: Sequence[Step], clock_now: Callable[[], float],
              backlog_s: Callable[[], float] | None = None) -> None:
        """The plan (or what is left of it) is about to run."""
        self.steps = steps
        self.timeline = Timeline([s.estimate_s for s in steps], clock_now,
                                 backlog_s=backlog_s)

    def step(self, index: int) -> None:
        """Step `index` starts: one line, with bench and wall time left."""
        if self.timeline is not None:
            self.timeline.start(index)
        self.show_step(index)

    def show_step(self, index: int) -> None:
        self.line(self.step_text(index, self.eta()))

    def step_done(self, index: int) -> None:
        """Step `index` finished: its wall time teaches the estimate."""
        if self.timeline is not None:
            self.timeline.finish(index)

    def end(self) -> None:
        """The plan ran to its end or was aborted; nothing more will move."""

    # -- what a step reports ----------------------------------------------------------
    def line(self, text: str) -> None:
        """A message to keep: a result, a stage reached."""
        self.stream.write(text + "\n")
        self.stream.flush()

    def warn(self, text: str) -> None:
        """A fault or a warning: never throttled, never overwritten."""
        self.line(text)

    def detail(self, text: str, force: bool = False) -> None:
        """A frequent free-text update; throttled here."""
        now = time.monotonic()
        if force or now - self._last_detail >= self.min_interval_s:
            self.line(text)
            self._last_detail = now

    def advance(self, done: float, total: float, text: str) -> None:
        """The current step's own progress: `done` of `total` (turns, seconds held).

        Shown by the live display's step bar only: a log keeps one line per step, with
        the results, faults and prompts (a day's ladder once left 127 "N of M turns
        timed" lines for 68 steps, and "0 of 30 s" lines that said nothing)."""

    def reading(self, name: str, label: str, *figures: Figure) -> None:
        """The latest value of a live quantity (per-turn rate deviation, FOG mean): shown
        by the live display only; a log keeps the result lines instead."""

    def result(self, label: str, *figures: Figure) -> None:
        """A line of results, rounded as the certificate rounds."""
        self.line(f"  {label}: {figures_text(figures)}")

    def ask(self, text: str) -> str:
        """Ask the operator; returns the answer typed (a terminal is checked by the caller)."""
        self.line(text)
        return self.read_answer()

    def summary(self, summary: Summary) -> None:
        """The end-of-run summary (the certificate's figures) on standard output; the
        verdicts coloured only where that is a terminal."""
        out = Console(file=self.out, highlight=False, soft_wrap=True)

        def styled(line: str, spans: list[tuple[int, int, str]]) -> None:
            text = Text(line)
            for start, end, style in spans:
                text.stylize(style, start, end)
            out.print(text)

        print_summary(summary, self._out_line,
                      styled if out.is_terminal and os.environ.get("TERM") != "dumb" else None)

    def _out_line(self, text: str) -> None:
        self.out.write(text + "\n")
        self.out.flush()

    def read_answer(self) -> str:
        """The operator's answer from standard input; the question goes to the console's
        stream, so standard output keeps only the summary and the run directory."""
        self.stream.write(ANSWER_PROMPT)
        self.stream.flush()
        line = sys.stdin.readline()
        if not line:
            raise EOFError("standard input closed while waiting for the operator")
        return line.rstrip("\n")

    def close(self) -> None:
        """Release the display; safe to call twice."""

    # -- shared wording ---------------------------------------------------------------
    def eta(self) -> Eta | None:
        return self.timeline.now() if self.timeline is not None else None

    def step_text(self, index: int, eta: Eta | None) -> str:
        step = self.steps[index]
        axis_w = max([6, *(len(s.axis or "") for s in self.steps)])
        head = (f"[{index + 1}/{len(self.steps)}] {step.axis or '':<{axis_w}} "
                f"{step.action:<9} {step.describe}")
        if eta is None:
            return head
        return f"{head}   ({eta.bench_text()} of bench time left; {eta_wall(eta)})"


def eta_wall(eta: Eta) -> str:
    """How long the operator still waits, in words: "about 1 min 12 s to go", with the
    measured pace where it is not real time (a simulated stand runs faster), and
    "time to go not yet measured" until a step with table time has been timed."""
    if eta.wall_left_s is None:
        return "time to go not yet measured"
    pace = ""
    if eta.speed is not None and abs(eta.speed - 1.0) > 0.05:
        pace = f", running {eta.speed:.3g}× real time"
    return f"about {eta.wall_text()} to go{pace}"
