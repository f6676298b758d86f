"""What a procedure kind provides to the engine (the plug-in interface)."""

from __future__ import annotations

from typing import Any, Protocol

from bench.clock import Clock
from bench.config import Config
from bench.engine import RunContext
from bench.instruments import Bench
from bench.journal import RunDir
from bench.plan import Plan, Step
from bench.schema import Map
from bench.simbench import SimBench
from bench.yamlfile import Problem


class ProcedureKind(Protocol):
    name: str

    def procedure_schema(self) -> Map:
        """The procedure file's keys (unknown keys are refused)."""

    def stand_schema(self) -> Map:
        """The stand file's keys for this kind (it may add instruments)."""

    def cross_check(self, cfg: Config) -> list[Problem]:
        """Checks that need both files: axes exist, rates within limits and ranges."""

    def build_plan(self, cfg: Config) -> Plan:
        """The steps, with bench-time estimates; no hardware touched."""

    def start_sim(self, cfg: Config) -> tuple[SimBench, dict[str, Any]]:
        """Start the twins; return the bench and the stand mapping pointing at them."""

    def open_bench(self, cfg: Config, stand: dict[str, Any], clock: Clock,
                   run: RunDir | None) -> Bench:
        """Open the instruments the plan needs."""

    def execute(self, step: Step, ctx: RunContext) -> None:
        """Do one step on the bench."""

    def analyze(self, run: RunDir, cfg: Config) -> dict[str, Any]:
        """result.json from the run directory's raw data alone."""
