"""The dwell's files, plan, steps and analysis, and the kind composed of its parts."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

from bench.core.config import COMMON_PROCEDURE_KEYS, IDENTITY, Config, StandSettings
from bench.core.engine import RunContext
from bench.core.instruments import Bench
from bench.core.journal import RunDir
from bench.core.plan import Duration, Plan, Step, check_actions
from bench.core.registry import StepHandler
from bench.core.schema import Key, Map, Num
from bench.core.simbench import SimBench
from bench.core.yamlfile import Problem
from bench.kind import Kind
from bench.report.codec import KindResult
from bench.report.dcc.parts import DccParts
from bench.report.station import StationParts
from drivers.clock import Clock
from drivers.json_types import JsonLike
from procedures.base import result_document, resume_whole
from tests.plugin_kind.events import Dwelt
from tests.plugin_kind.report import DwellCertificate, DwellDcc, DwellRecords

NAME = "dwell"
TITLE = "Dwell on the bench clock"
SIM = Map({"seed": Key(Num(min=0, integer=True), False, "the simulated bench's seed")})


@dataclass(frozen=True)
class DwellSettings:
    """The procedure as the dwell reads it: frozen settings (a dataclass or a Struct)."""

    dwell_s: float


class DwellFiles:
    """Its files (the `settings` part): a dwell and a tolerance; no axis, no instrument."""

    def procedure_schema(self) -> Map:
        return Map({**COMMON_PROCEDURE_KEYS,
                    "dwell_s": Key(Num(min=0, exclusive_min=True, unit="s"), True),
                    "tolerance_s": Key(Num(min=0, exclusive_min=True, unit="s"), True)})

    def stand_schema(self) -> Map:
        return Map({"stand": Key(IDENTITY, True), "axes": Key(Map({})),
                    "sim": Key(SIM, False, "present: the dwell runs on the simulated "
                                           "bench's clock")})

    def cross_check(self, cfg: Config) -> list[Problem]:
        return []

    def parse(self, cfg: Config) -> DwellSettings:
        """The dwell's one setting (bench/core/registry.py KindSettings.parse)."""
        return DwellSettings(float(cfg.procedure["dwell_s"]))

    def notes(self, cfg: Config) -> list[str]:
        return []


class DwellSteps:
    """Its bench (the `steps` part): the simulated bench's clock, no instrument; one
    action, `dwell`."""

    def __init__(self) -> None:
        self.handlers: Mapping[str, StepHandler] = {"dwell": self.dwell}

    def start_sim(self, cfg: Config) -> tuple[SimBench, StandSettings]:
        """The simulated bench with no twin: its clock alone."""
        sim = SimBench(cfg.stand_settings, axes=[])
        return sim, sim.start()

    def open_bench(self, cfg: Config, stand: StandSettings, clock: Clock,
                   run: RunDir | None) -> Bench:
        return Bench()

    def execute(self, step: Step, ctx: RunContext) -> None:
        self.handlers[step.action](step, ctx)

    def dwell(self, step: Step, ctx: RunContext) -> None:
        start = ctx.clock.now()
        ctx.clock.sleep(step.params_as(Duration).duration_s)
        ctx.run.write(Dwelt(waited_s=ctx.clock.now() - start))


class DwellPlan:
    """Its plan (the `plan` part): one step, resumed whole."""

    resume_plan = staticmethod(resume_whole)

    def build_plan(self, cfg: Config) -> Plan:
        dwell = float(cfg.procedure["dwell_s"])
        return check_actions(Plan(cfg.procedure.get("title", TITLE),
                                  (Step("dwell", None, f"wait {dwell:g} s", dwell, "dwell",
                                        Duration(dwell)),)),
                             DwellSteps().handlers)


class DwellAnalysis:
    """Its result.json (the `analysis` part): the time waited, its error checked."""

    def analyze(self, run: RunDir, cfg: Config) -> KindResult[dict[str, JsonLike]]:
        events = run.events()
        waited = [e.waited_s for e in events if isinstance(e, Dwelt)]
        dwell, tol = float(cfg.procedure["dwell_s"]), float(cfg.procedure["tolerance_s"])
        checks = []
        error = None
        if waited:
            error = waited[-1] - dwell
            ok = abs(error) <= tol
            checks.append({"axis": None, "quantity": "dwell_time", "unit": "s",
                           "value_s": error, "u_s": 0.0, "tolerance_s": tol,
                           "rule": "simple", "verdict": "pass" if ok else "fail",
                           "reason": f"|{error:.3g}| s {'<=' if ok else '>'} {tol:g} s"})
        return result_document(run, cfg, events, complete=bool(waited), checks=checks,
                               rule="simple", method={"dwell_s": dwell},
                               dwell={"waited_s": waited[-1] if waited else None,
                                      "error_s": error})


@dataclass(frozen=True)
class Dwell:
    """Waits `dwell_s` of bench time and reports how long it waited: the parts above,
    composed (a light kind: every part imported with it)."""

    name: str = NAME
    settings: DwellFiles = DwellFiles()
    plan: DwellPlan = DwellPlan()
    steps: DwellSteps = DwellSteps()
    analysis: DwellAnalysis = DwellAnalysis()
    certificate: DwellCertificate = DwellCertificate()
    dcc: DccParts = DwellDcc()
    records: DwellRecords = DwellRecords()
    station: StationParts = StationParts()


KIND: Kind = Dwell()
QUIET: Kind = dataclasses.replace(Dwell(), dcc=DccParts())
