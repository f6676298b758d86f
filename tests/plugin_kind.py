"""A third procedure kind, `dwell`, written the way README "How to add a procedure" says:
it imports only what a procedure may (the engine's interfaces, the certificate's and the
DCC's vocabulary, procedures.base) and is registered by name, as an entry point would
register it (tests/test_procedure_plugin.py). Its plan is one step that waits on the bench
clock; no instrument is opened. On twins (a stand file with a `sim:` block, or `--sim`)
that clock is the simulated bench's, which has no twin to start. Its analysis reads the
journal back and states two figures, the time waited and its error against the dwell
asked for, the error checked against a tolerance.

A kind is a name and its parts, each an attribute with its own interface
(bench/core/registry.py `ProcedureKind`): `settings` (its files), `plan`, `steps` (one
handler per action; the plan is checked against them when built), `analysis`,
`certificate`, `dcc` and `records`. Its figures reach the records, `bench history`, the
trend plot and the console summary through their declaration alone (the `records` part, a
`bench.report.figures.DeclaredFigures`).

`KIND` has a DCC part of its own (`bench.report.dcc.parts.DccParts`); `QUIET` is the same
kind with the neutral `DccParts()`, which still gives a valid DCC.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from lxml import etree

from bench.core.config import COMMON_PROCEDURE_KEYS, IDENTITY, Config, StandSettings
from bench.core.engine import RunContext
from bench.core.events import Event
from bench.core.instruments import Bench
from bench.core.journal import RunDir
from bench.core.plan import Duration, Plan, Step, check_actions
from bench.core.registry import ProcedureKind, StepHandler
from bench.core.schema import Key, Map, Num
from bench.core.simbench import SimBench
from bench.core.yamlfile import Problem
from bench.report.certificate.model import Para, Section, Table
from bench.report.certificate.parts import CertificateParts, Sources, num
from bench.report.dcc import units as U
from bench.report.dcc import vocab as V
from bench.report.dcc.conformity import Checks, judge
from bench.report.dcc.parts import DccParts
from bench.report.dcc.xml import el, name, quantity
from bench.report.figures import DeclaredFigures, FigureSpec, Trend
from drivers.clock import Clock
from procedures.base import result_document, resume_whole

NAME = "dwell"
TITLE = "Dwell on the bench clock"
WAITED = V.RB + "dwellTime"      # the kind's own refType


#: what the dwell reports: the time waited (trended, no tolerance) and its error against
#: the dwell asked for (the check's quantity, drawn inside its tolerance band)
FIGURES = (
    FigureSpec("dwell_waited_s", "time waited", "s",
               "bench time between the start and the end of the dwell step",
               "dwell.waited_s", trend=Trend(), listed=True),
    FigureSpec("dwell_error_s", "dwell error", "s", "time waited - dwell_s",
               "dwell.error_s", check="dwell_time", shown_unit="ms",
               scale=1e3, trend=Trend("sym"), listed=True),
)
SIM = Map({"seed": Key(Num(min=0, integer=True), False, "the simulated bench's seed")})


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

    def parse(self, cfg: Config) -> float:
        """The dwell's one setting (bench/core/registry.py KindSettings.parse)."""
        return float(cfg.procedure["dwell_s"])

    def notes(self, cfg: Config) -> list[str]:
        return []


class Dwelt(Event, tag="dwelt", frozen=True):
    """The kind's own journal record, declared beside its steps (bench/core/events.py)."""

    waited_s: float


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

    def analyze(self, run: RunDir, cfg: Config) -> dict[str, Any]:
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


class DwellCertificate(CertificateParts):
    """Its part of the certificate: a name, its check's quantity, one section."""

    certificate_procedure_name = "dwell (a test plug-in)"
    certificate_quantities = {"dwell_time": "time waited"}

    def certificate_sections(self, src: Sources, number: str,
                             checks: Sequence[Mapping[str, Any]]) -> list[Section]:
        waited = num(src.frame.part("dwell").get("waited_s"))
        text = "not recorded" if waited is None else f"{waited:.3f}"
        return [Section(number, "Dwell results", (
            Table(("Quantity", "Value, s"), (("time waited", text),)),
            Para("Bench time between the start and the end of the dwell step."),))]


class DwellDcc(DccParts):
    """Its part of the DCC: the item, and its one figure."""

    def dcc_item(self, src: Sources) -> tuple[str, Sequence[str]]:
        return "bench clock", ()

    def dcc_results(self, results: etree._Element, src: Sources, checks: Checks) -> None:
        waited = num(src.frame.part("dwell").get("waited_s"))
        if waited is None:
            return
        mr = el(results, "measurementResult", id="dwell", ref_id="item")
        name(mr, "Dwell")
        result = el(el(mr, "results"), "result", id="dwellResult", ref_type=V.MEASURED)
        name(result, "Time waited on the bench clock")
        data = el(result, "data")
        node = quantity(data, "dwell_waited", "time waited", WAITED, waited, U.SECOND,
                        label="dwell.waited_s")
        judge(node, checks.take(None, None, "dwell_time"), U.SECOND)


class DwellRecords(DeclaredFigures):
    """Its figures for the records, `bench history`, the trend plot and the summary."""

    figures = FIGURES


@dataclass(frozen=True)
class Dwell:
    """Waits `dwell_s` of bench time and reports how long it waited: the parts above,
    composed (a light kind: every part imported with it)."""

    name: str = NAME
    settings: DwellFiles = DwellFiles()
    plan: DwellPlan = DwellPlan()
    steps: DwellSteps = DwellSteps()
    analysis: DwellAnalysis = DwellAnalysis()
    certificate: CertificateParts = DwellCertificate()
    dcc: DccParts = DwellDcc()
    records: DwellRecords = DwellRecords()


KIND: ProcedureKind = Dwell()
QUIET: ProcedureKind = dataclasses.replace(Dwell(), dcc=DccParts())
