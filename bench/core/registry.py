"""Procedure kinds as plug-ins, found by entry point (group `ratebench.procedures`).

A procedure package registers itself in its distribution's metadata:

    [project.entry-points."ratebench.procedures"]
    my-kind = "my_package.my_kind:KIND"

so the engine, the CLI, the certificate, the records and the console find it without
naming it: adding a procedure touches no file outside its own package and its entry
point. A kind is a name and its parts, held as attributes (`ProcedureKind` below):
`settings` (the files), `plan`, `steps` (twins, instruments, one handler per action),
`analysis` (result.json), `certificate` and `dcc` (a
`bench.report.certificate.parts.CertificateParts` and a `bench.report.dcc.parts.DccParts`,
whose neutral answers a kind overrides) and `records`, which answers the small
capabilities below, each asked for by isinstance, each optional: its figures
(`ReportsFigures`: the records, `bench history`, the trend plot, the station view, the
summary), its summary cells, its own instruments' check values, the shape of its part of
result.json, its per-axis rates and pairs
(`bench.report.axes_view.ShowsAxes`), a sample result for previews and
starter files for `bench init`.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Protocol, runtime_checkable

from bench.core.kind_index import registered

if TYPE_CHECKING:
    # The interface's types, for its hints only: `bench validate` and `bench schema` find
    # a kind through this module without loading the engine, the instruments or the
    # twins; and the certificate's package imports this module when it is loaded.
    from bench.core.config import Config, StandSettings
    from bench.core.engine import RunContext
    from bench.core.instruments import Bench
    from bench.core.journal import RunDir
    from bench.core.plan import Plan, Step
    from bench.core.schema import Map
    from bench.core.simbench import SimBench
    from bench.core.yamlfile import Problem
    from bench.report.certificate.model import Document
    from bench.report.figures import FigureSpec, FigureValue, InstrumentCheck, SummaryCut
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

    def parse(self, cfg: Config) -> object:
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

    def analyze(self, run: RunDir, cfg: Config) -> dict[str, object]:
        """The result document (bench analyze reproduces it byte for byte)."""


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

    @property
    def certificate(self) -> object:
        """Its part of the certificate: a `bench.report.certificate.parts.CertificateParts`
        (`CertificateParts()`: nothing of its own). Typed `object` here, as `records` is:
        the report layer sits above this one, and the certificate asks by isinstance."""

    @property
    def dcc(self) -> object:
        """Its part of the DCC: a `bench.report.dcc.parts.DccParts` (`DccParts()`:
        nothing of its own), asked for by isinstance."""

    @property
    def records(self) -> object:
        """Its answers to the capabilities below, each asked for by isinstance."""


# -- what a kind's `records` part may answer: small capabilities, each asked for by isinstance

@runtime_checkable
class ReportsFigures(Protocol):
    """Its figures, declared (bench/report/figures.py), and read from a result.json: what the
    records keep, `bench history` lists, the trend plot draws and the station shows.
    `bench.report.figures.DeclaredFigures` reads them at their declared paths."""

    figures: tuple[FigureSpec, ...]

    def figure_values(self, result: Mapping[str, object]) -> list[FigureValue]:
        """Every figure of this result, with U (k = 2) where it has one."""


@runtime_checkable
class SummarisesRun(Protocol):
    """Which cells of its certificate the console summary shows (otherwise the summary
    lists the declared figures)."""

    def summary_cut(self, doc: Document) -> SummaryCut:
        """The certificate's tables and fields the console prints at the end of a run."""


@runtime_checkable
class ChecksInstruments(Protocol):
    """Check values of the instruments only the kind knows (measurement assurance,
    docs/method.md C1), from the result and the stand file the run used; their
    quantities: key -> (unit, what the control chart calls it)."""

    check_quantities: Mapping[str, tuple[str, str]]

    def instrument_checks(self, result: Mapping[str, object], stand: Mapping[str, object]
                          ) -> list[InstrumentCheck]:
        """The kind's own instruments' check values in this run."""


@runtime_checkable
class HasSampleResult(Protocol):
    """A hand-made result.json of the kind, for previews of its certificate."""

    def sample_result(self) -> dict[str, object]:
        """A result whose printed figures are worked out by hand."""


@runtime_checkable
class HasStarterFiles(Protocol):
    """Commented stand and procedure files that validate, for `bench init`."""

    def starter_files(self, real: bool) -> dict[str, str]:
        """File name -> text (stand.yaml, procedure.yaml); `real`: no `sim:` block."""


def _registered() -> dict[str, str]:
    """procedure name -> "module:attribute" of its kind (bench/core/kind_index.py)."""
    return registered()


def procedure_names() -> list[str]:
    """Every installed procedure kind's name (the `procedure:` key of a procedure file)."""
    return sorted(_registered())


def procedure_kind(name: str) -> ProcedureKind:
    """The kind registered under `name` (KeyError if none is)."""
    module, _, attr = _registered()[name].partition(":")
    kind: ProcedureKind = getattr(importlib.import_module(module), attr or "KIND")
    return kind


def installed_kind(name: str | None) -> ProcedureKind | None:
    """The kind of that name if it is installed here, else None (a run recorded by a kind
    this installation lacks is still listed, its figures by their stored names)."""
    try:
        return procedure_kind(str(name)) if name else None
    except (KeyError, ImportError, AttributeError):
        return None


def installed_records(name: str | None) -> object | None:
    """The `records` part of the kind of that name if it is installed here, else None
    (the capabilities above are asked of it by isinstance)."""
    kind = installed_kind(name)
    return kind.records if kind is not None else None


def declared_figures(names: Sequence[str] | None = None) -> tuple[FigureSpec, ...]:
    """The figures the named kinds declare (every installed kind's when None), in the
    kinds' order, a quantity declared twice taken from the first kind."""
    out: list[FigureSpec] = []
    seen: set[str] = set()
    for name in dict.fromkeys(procedure_names() if names is None else names):
        records = installed_records(name)
        if isinstance(records, ReportsFigures):
            for spec in records.figures:
                if spec.quantity not in seen:
                    seen.add(spec.quantity)
                    out.append(spec)
    return tuple(out)
