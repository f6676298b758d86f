"""Procedure kinds as plug-ins, found by entry point (group `ratebench.procedures`).

A procedure package registers itself in its distribution's metadata:

    [project.entry-points."ratebench.procedures"]
    rate-ladder = "procedures.rate_ladder:KIND"

so the engine, the CLI and the certificate find it without naming it: adding a
procedure touches no file outside its own package and its entry point. The kind's
interface (what the engine and the certificate ask of it) is `ProcedureKind` below; its
certificate hooks, with neutral answers, come from `bench.certificate.parts.CertificateParts`.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Mapping, Sequence
from functools import cache
from importlib.metadata import entry_points
from typing import TYPE_CHECKING, Any, Protocol

from bench.config import Config, StandSettings
from bench.engine import RunContext
from bench.instruments import Bench
from bench.journal import RunDir
from bench.plan import Plan, Step
from bench.schema import Map
from bench.simbench import SimBench
from bench.yamlfile import Problem
from drivers.clock import Clock

if TYPE_CHECKING:   # the certificate's package imports this module when it is loaded
    from bench.certificate.model import Section
    from bench.certificate.parts import Sources

GROUP = "ratebench.procedures"
#: where an install whose metadata predates the entry points finds the kinds (an old
#: editable install): every module of this package that defines `KIND`
FALLBACK_PACKAGE = "procedures"


class ProcedureKind(Protocol):
    """What a procedure kind provides to the engine (the plug-in interface)."""

    name: str

    def procedure_schema(self) -> Map:
        """The procedure file's keys (unknown keys are refused)."""

    def stand_schema(self) -> Map:
        """The stand file's keys for this kind (it may add instruments)."""

    def cross_check(self, cfg: Config) -> list[Problem]:
        """Checks that need both files: axes exist, rates within limits and ranges."""

    def build_plan(self, cfg: Config) -> Plan:
        """The steps, with bench-time estimates; no hardware touched."""

    def parse(self, cfg: Config) -> object:
        """The validated procedure as this kind's frozen settings (the loader keeps them
        in `Config.settings`; nothing below the loader reads the procedure mapping)."""

    def start_sim(self, cfg: Config) -> tuple[SimBench, StandSettings]:
        """Start the twins; return the bench and the stand settings pointing at them."""

    def open_bench(self, cfg: Config, stand: StandSettings, clock: Clock,
                   run: RunDir | None) -> Bench:
        """Open the instruments the plan needs."""

    def execute(self, step: Step, ctx: RunContext) -> None:
        """Do one step on the bench."""

    def resume_plan(self, plan: Plan, run: RunDir) -> Plan:
        """What a --resume runs of `plan` (the units not done); `procedures.base.StepDispatch`
        answers "all of it"."""

    def analyze(self, run: RunDir, cfg: Config) -> dict[str, Any]:
        """result.json from the run directory's raw data alone."""

    def certificate_sections(self, src: Sources, number: str,
                             checks: Sequence[Mapping[str, Any]]) -> list[Section]:
        """The certificate's results section `number` (and its subsections) from
        result.json. The other questions the certificate asks (item, method, deviations,
        annexes, statements) and their neutral answers: inherit `CertificateParts`."""


@cache
def _registered() -> dict[str, str]:
    """procedure name -> "module:attribute" of its kind."""
    found = {ep.name: ep.value for ep in entry_points(group=GROUP)}
    if found:
        return found
    try:
        package = importlib.import_module(FALLBACK_PACKAGE)
    except ImportError:
        return {}
    for info in pkgutil.iter_modules(package.__path__, f"{FALLBACK_PACKAGE}."):
        kind = getattr(importlib.import_module(info.name), "KIND", None)
        if kind is not None:
            found[kind.name] = f"{info.name}:KIND"
    return found


def procedure_names() -> list[str]:
    """Every installed procedure kind's name (the `procedure:` key of a procedure file)."""
    return sorted(_registered())


def procedure_kind(name: str) -> ProcedureKind:
    """The kind registered under `name` (KeyError if none is)."""
    module, _, attr = _registered()[name].partition(":")
    return getattr(importlib.import_module(module), attr or "KIND")
