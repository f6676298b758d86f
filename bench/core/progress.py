"""What the engine and the procedure kinds tell the operator's console, and nothing more.

The console itself (a live display, plain lines, JSON lines) lives in the top layer
(`bench/app/console/`), next to the certificate whose rounding it shares. Below it, steps say
what happened in plain words and hand over numbers as `Figure`s, unrounded: the console
rounds each one as the certificate would (U to two significant digits, the value to match;
a fraction in ppm or %), so a procedure never formats a measured number itself.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

from bench.core.plan import Step

RELATIVE = "rel"  # a Figure's unit for a plain fraction: printed in ppm or % as the certificate


@dataclass(frozen=True)
class Figure:
    """A measured number for the console: value and U (k = 2) in the same unit."""

    name: str
    value: float | None
    u: float | None = None
    unit: str = ""          # "°/s", "°/h", or RELATIVE
    signed: bool = False
    digits: int = 4         # significant digits when there is no U
    magnitude: bool = False  # a size (a σ, an amplitude): "< limit" when not resolved


class Progress(Protocol):
    """The console as the engine and the steps see it (bench/app/console/ implements it)."""

    interactive: bool

    def begin(self, steps: Sequence[Step], clock_now: Callable[[], float],
              backlog_s: Callable[[], float] | None = None) -> None:
        """The plan (or what is left of it) starts; `clock_now` is the bench clock;
        `backlog_s` the wall time still owed by work done beside the steps (a pair's
        analysis in the worker), which the end of the run waits for."""

    def step(self, index: int) -> None:
        """Step `index` starts."""

    def step_done(self, index: int) -> None:
        """Step `index` finished."""

    def end(self) -> None:
        """Nothing more will move (completed or aborted)."""

    def line(self, text: str) -> None:
        """A message to keep."""

    def warn(self, text: str) -> None:
        """A fault or a warning: never throttled, never overwritten."""

    def detail(self, text: str, force: bool = False) -> None:
        """A frequent free-text update."""

    def advance(self, done: float, total: float, text: str) -> None:
        """The current step's own progress: `done` of `total` (turns, seconds held)."""

    def reading(self, name: str, label: str, *figures: Figure) -> None:
        """The latest value of a live quantity (a per-turn rate deviation, the FOG mean)."""

    def result(self, label: str, *figures: Figure) -> None:
        """A line of results: `label: name = value ± U unit, ...`."""

    def ask(self, text: str) -> str:
        """Ask the operator at the terminal; returns what was typed."""

    def close(self) -> None:
        """Release the display; safe to call twice."""
