"""The live display on a terminal (rich): where the run is, how long it has left, what it
measured last; messages, faults and prompts printed above it, never overwritten.

    ━━━━━━━━╸━━━━━━━━━━━  step 23/58   41 %  bench time left 9 min 41 s  about 6.3 s to go, running 92× real time
                          outer acquire: 4 turns at -10 deg/s (half 2/3, 2 min 24 s)
    ━━━━━━━━━╸━━━━━━━━━━  2 of 4 turns timed at -10 deg/s, 1 min 12 s left
    latest per-turn rate deviation: outer +10 deg/s turn 2: −0.0792 ppm
    latest FOG mean: +9.99702 °/s
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from typing import IO

from rich.console import Console, Group, RenderableType
from rich.live import Live
from rich.progress_bar import ProgressBar
from rich.table import Table
from rich.text import Text

from bench.app.console.figures import figures_text
from bench.app.console.plain import PlainConsole, eta_wall
from bench.core.plan import Step
from bench.core.progress import Figure

BAR_WIDTH = 20


class _View:
    """Rebuilt at every refresh (4 per second), so the times left run down between calls."""

    def __init__(self, owner: LiveConsole) -> None:
        self.owner = owner

    def __rich__(self) -> RenderableType:
        o = self.owner
        with o.lock:
            step_progress = o.step_progress
            readings = dict(o.readings)
        eta = o.eta()
        if eta is None or eta.index < 0:
            return Text("starting…", style="dim")
        step = o.steps[eta.index]
        if step_progress is not None:
            done, total, text = step_progress
            fraction = done / total if total > 0 else 0.0
        else:
            fraction, text = eta.step_fraction, ""
        grid = Table.grid(padding=(0, 1), expand=True)
        grid.add_column(width=BAR_WIDTH, no_wrap=True)
        grid.add_column(ratio=1, no_wrap=True, overflow="ellipsis")
        grid.add_row(ProgressBar(total=1000, completed=eta.done_fraction * 1000,
                                 width=BAR_WIDTH),
                     Text.assemble((f"step {eta.index + 1}/{eta.steps}", "bold"),
                                   f"  {eta.done_fraction * 100:3.0f} %"
                                   f"  bench time left {eta.bench_text()}  ",
                                   (eta_wall(eta), "cyan"), no_wrap=True,
                                   overflow="ellipsis"))
        grid.add_row(Text(""), Text.assemble((f"{step.axis or ''} {step.action}: ", "bold"),
                                             step.describe, no_wrap=True,
                                             overflow="ellipsis"))
        grid.add_row(ProgressBar(total=1000, completed=min(max(fraction, 0.0), 1.0) * 1000,
                                 width=BAR_WIDTH),
                     Text(text, no_wrap=True, overflow="ellipsis"))
        rows: list[RenderableType] = [grid]
        for name, value in readings.items():
            rows.append(Text(f"latest {name}: {value}", style="dim", no_wrap=True,
                             overflow="ellipsis"))
        return Group(*rows)


class LiveConsole(PlainConsole):
    """A rich live display on a terminal stream; everything else as the plain console."""

    interactive = True

    def __init__(self, stream: IO[str], refresh_per_second: float = 4.0,
                 out: IO[str] | None = None) -> None:
        super().__init__(stream, out=out)
        self.console = Console(file=stream, highlight=False, soft_wrap=False)
        self.lock = threading.Lock()
        self.step_progress: tuple[float, float, str] | None = None
        self.readings: dict[str, str] = {}
        self.live = Live(_View(self), console=self.console, auto_refresh=True,
                         refresh_per_second=refresh_per_second, transient=False,
                         redirect_stdout=True, redirect_stderr=True)
        self._running = False

    def begin(self, steps: Sequence[Step], clock_now: Callable[[], float],
              backlog_s: Callable[[], float] | None = None) -> None:
        super().begin(steps, clock_now, backlog_s)
        self._start()

    def _start(self) -> None:
        if not self._running:
            self.live.start()
            self._running = True

    def _stop(self) -> None:
        if self._running:
            self.live.stop()
            self._running = False

    def show_step(self, index: int) -> None:
        with self.lock:
            self.step_progress = None
        if self._running:
            self.live.refresh()

    def end(self) -> None:
        if self._running:
            self.live.refresh()
        self._stop()

    def line(self, text: str) -> None:
        self.console.print(Text(text))

    def warn(self, text: str) -> None:
        self.console.print(Text(text, style="bold yellow"))

    def detail(self, text: str, force: bool = False) -> None:
        with self.lock:
            done, total, _ = self.step_progress or (0.0, 0.0, "")
            self.step_progress = (done, total, text.strip())

    def advance(self, done: float, total: float, text: str) -> None:
        with self.lock:
            first = self.step_progress is None
            self.step_progress = (done, total, text)
        if first and self._running:
            # a step's own bar is drawn at least once, however fast the paced clock runs
            # it through (a 2 s settle can take 20 ms of wall time on the twins)
            self.live.refresh()

    def reading(self, name: str, label: str, *figures: Figure) -> None:
        text = f"{figures_text(figures)} ({label})" if label else figures_text(figures)
        with self.lock:
            self.readings[name] = text

    def ask(self, text: str) -> str:
        """Pause the display, ask on the terminal, carry on."""
        running = self._running
        self._stop()
        try:
            self.console.print(Text(text, style="bold magenta"))
            return self.read_answer()
        finally:
            if running:
                self._start()

    def close(self) -> None:
        self._stop()
