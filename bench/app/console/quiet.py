"""`bench run --quiet`: only what needs a person (faults, warnings, prompts)."""

from __future__ import annotations

from bench.app.console.plain import PlainConsole
from bench.app.console.report import Summary


class QuietConsole(PlainConsole):
    def show_step(self, index: int) -> None:
        pass

    def line(self, text: str) -> None:
        pass

    def detail(self, text: str, force: bool = False) -> None:
        pass

    def warn(self, text: str) -> None:
        super().line(text)

    def ask(self, text: str) -> str:
        super().line(text)
        return self.read_answer()

    def summary(self, summary: Summary) -> None:
        self._out_line(f"verdict: {summary.verdict}")
