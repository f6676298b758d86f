"""Procedure kinds as plug-ins, found by entry point (group `ratebench.procedures`).

A procedure package registers itself in its distribution's metadata:

    [project.entry-points."ratebench.procedures"]
    my-kind = "my_package.my_kind:KIND"

so the engine, the CLI, the certificate, the records and the console find it without
naming it: adding a procedure touches no file outside its own package and its entry
point. A kind is a name and its parts, held as attributes. Its light parts are stated
here (`ProcedureKind`): `settings` (the files), `plan`, `steps` (twins, instruments, one
handler per action) and `analysis` (result.json), which `bench validate`, the engine and
`bench analyze` use. The parts that report on a run (`certificate`, `dcc`, `records`,
`station`) are typed one layer up, over the report layer's types, in bench/kind.py
(`Kind`), which also finds a kind with all of them.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Protocol

from bench.core.kind_index import registered

if TYPE_CHECKING:
    # The interface's types, for its hints only: `bench validate` and `bench schema` find
    # a kind through this module without loading the engine, the instruments or the
    # twins; and the certificate's package imports this module when it is loaded.
    from bench.core.config import Config, KindParsed, StandSettings
    from bench.core.engine import RunContext
    from bench.core.instruments import Bench
    from bench.core.journal import RunDir
    from bench.core.plan import Plan, Step
    from bench.core.schema import Map
    from bench.core.simbench import SimBench
    from bench.core.yamlfile import Problem
    from bench.report.codec import KindResult, ResultPart
    from drivers.clock import Clock



#: one step's handler: does the step on the bench (a kind's `steps.handlers[action]`)
StepHandler = Callable[["Step", "RunContext"], None]


class KindSettings(Protocol):
    """The files a kind reads: loaded without numpy, the analysis, the certificate or the
    records (`bench validate` and `bench schema` load this part alone)."""

    def procedure_schema(self) -> Map:
        """The procedure file's keys (unknown keys are refused)."""

    def stand_schema(self) -> Map:
        """The stand file's keys for this kind (it may add instruments)."""

    def cross_check(self, cfg: Config) -> list[Problem]:
        """Checks that need both files: axes exist, rates within limits and ranges."""

    def parse(self, cfg: Config) -> KindParsed:
        """The validated procedure as this kind's frozen settings (the loader keeps them
        in `Config.settings`; nothing below the loader reads the procedure mapping)."""

    def notes(self, cfg: Config) -> list[str]:
        """Advice `bench validate` prints beside 'valid' (nothing wrong, something unstated)."""


class KindPlan(Protocol):
    """The steps of a run and of its resumption; no hardware touched."""

    def build_plan(self, cfg: Config) -> Plan:
        """The steps, with bench-time estimates; every action one the kind's steps handle
        (`bench.core.plan.check_actions`)."""

    def resume_plan(self, plan: Plan, run: RunDir) -> Plan:
        """What a --resume runs of `plan` (the units not done)."""


class KindSteps(Protocol):
    """The bench: its twins, its instruments, and one typed handler per action."""

    @property
    def handlers(self) -> Mapping[str, StepHandler]:
        """action -> what does it; the plan is checked against these keys when built."""

    def start_sim(self, cfg: Config) -> tuple[SimBench, StandSettings]:
        """Start the twins; return the bench and the stand settings pointing at them."""

    def open_bench(self, cfg: Config, stand: StandSettings, clock: Clock,
                   run: RunDir | None) -> Bench:
        """Open the instruments the plan needs."""

    def execute(self, step: Step, ctx: RunContext) -> None:
        """Do one step on the bench (its action's handler)."""


class KindAnalysis(Protocol):
    """result.json from the run directory's raw data alone."""

    def analyze(self, run: RunDir, cfg: Config) -> KindResult[ResultPart]:
        """The run's result, typed: the shared frame and the kind's body (result.json is
        its encoding, bench/report/codec.py; bench analyze reproduces it byte for byte)."""


class ProcedureKind(Protocol):
    """What a procedure kind is (the plug-in interface): a name and its parts, each an
    attribute with its own interface. The light parts (`settings`, `plan`) are imported
    with the kind; the heavy ones (numpy, the analysis, the certificate, the records)
    when first used, so that `bench validate` and `bench schema` load none of them."""

    @property
    def name(self) -> str:
        """The `procedure:` key of its procedure files."""

    @property
    def settings(self) -> KindSettings:
        """Schemas, parse, cross-checks and notes."""

    @property
    def plan(self) -> KindPlan:
        """build_plan, resume_plan."""

    @property
    def steps(self) -> KindSteps:
        """Twins, instruments and the step handlers."""

    @property
    def analysis(self) -> KindAnalysis:
        """The run's result.json."""


def _registered() -> dict[str, str]:
    """procedure name -> "module:attribute" of its kind (bench/core/kind_index.py)."""
    return registered()


def procedure_names() -> list[str]:
    """Every installed procedure kind's name (the `procedure:` key of a procedure file)."""
    return sorted(_registered())


def procedure_kind(name: str) -> ProcedureKind:
    """The kind registered under `name` (KeyError if none is)."""
    module, _, attr = kind_location(name).partition(":")
    kind: ProcedureKind = getattr(importlib.import_module(module), attr or "KIND")
    return kind


def kind_location(name: str) -> str:
    """"module:attribute" of the kind registered under `name` (KeyError if none is)."""
    return _registered()[name]
