"""The procedure-kind interface, typed part by part, so that mypy checks a kind.

bench/core/registry.py states a kind's light parts (`settings`, `plan`, `steps`,
`analysis`): what `bench validate`, the engine and the analysis need, below the report
layer. The parts that write about a run (its certificate, its DCC, its records and the
station's page) are stated here, one layer up, as Protocols over the report layer's
types: a kind declared `KIND: Kind = ...` is checked against every part when mypy runs,
and a part of the wrong type is an error there, not at a customer's run (issue 61).

A kind's `records` part answers the questions every consumer asks (`RecordsPart`); a
few capabilities only some kinds have stay small Protocols asked for by isinstance
(`SummarisesRun`, `ChecksInstruments`, `HasSampleResult`, `HasStarterFiles`; the
certificate part's `result_conform` is bench/report/certificate/sources.py's `ConformsResult`).
Nothing here names a kind.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Protocol, runtime_checkable

from bench.core.registry import ProcedureKind, kind_location, procedure_names
from bench.core.yamlfile import YamlValue

if TYPE_CHECKING:
    from lxml import etree

    from bench.core.events import LiveRow
    from bench.report.certificate.model import Block, Document, Section
    from bench.report.certificate.parts import Check, Sources, TitledBlocks
    from bench.report.dcc.conformity import Checks
    from bench.report.figures import FigureSpec, FigureValue, InstrumentCheck, SummaryCut
    from bench.report.result_frame import ResultFrame
    from bench.report.sample_result import SampleResult
    from bench.report.station import PageTable


class CertificatePart(Protocol):
    """What the certificate asks a kind (`bench.report.certificate.parts.CertificateParts`
    answers each neutrally; a kind subclasses it and overrides what it has to say)."""

    @property
    def certificate_procedure_name(self) -> str: ...
    @property
    def certificate_procedure_id(self) -> tuple[str, str, str] | None: ...
    @property
    def certificate_stand_label(self) -> str: ...
    @property
    def certificate_measured(self) -> tuple[tuple[str, str], ...]: ...
    @property
    def certificate_quantities(self) -> Mapping[str, str]: ...
    @property
    def certificate_unsigned(self) -> frozenset[str]: ...

    def certificate_recognises(self, src: Sources) -> bool: ...
    def certificate_item(self, src: Sources) -> tuple[str, str]: ...
    def certificate_identification(self, src: Sources) -> Sequence[tuple[str, str]]: ...
    def certificate_method(self, src: Sources) -> Sequence[Block]: ...
    def certificate_method_deviations(self, src: Sources) -> Sequence[Block]: ...
    def certificate_run_deviations(self, src: Sources) -> Sequence[str]: ...
    def certificate_checks(self, src: Sources) -> list[Check]: ...
    def certificate_sections(self, src: Sources, number: str,
                             checks: Sequence[Check]) -> list[Section]: ...
    def certificate_annexes(self, src: Sources) -> Sequence[TitledBlocks]: ...
    def certificate_statements(self, statements: Sequence[str]) -> list[str]: ...


class DccPart(Protocol):
    """What the DCC writer asks a kind (`bench.report.dcc.parts.DccParts`, neutral)."""

    def dcc_item(self, src: Sources) -> tuple[str, Sequence[str]]: ...
    def dcc_used_methods(self, src: Sources) -> tuple[str, Sequence[str]]: ...
    def dcc_results(self, results: etree._Element, src: Sources, checks: Checks) -> None: ...


class RecordsPart(Protocol):
    """Its figures, declared (bench/report/figures.py), and read from a result.json: what the
    records keep, `bench history` lists, the trend plot draws and the station shows.
    `bench.report.figures.DeclaredFigures` reads them at their declared paths."""

    @property
    def figures(self) -> tuple[FigureSpec, ...]: ...

    def figure_values(self, frame: ResultFrame) -> list[FigureValue]:
        """Every figure of this result (decoded once by the reader: `ResultFrame`; the kind
        decodes its own part from it with its codec), with U (k = 2) where it has one."""
        ...


class StationPart(Protocol):
    """What the station's run pages show of a kind's results, worded by the certificate's
    rounding rule (`bench.report.station.StationParts` answers with nothing: the pages
    then list the kind's declared figures)."""

    def live_table(self, rows: Sequence[LiveRow]) -> PageTable | None:
        """The first looks as they come (the rows the kind's events give, `Event.live_rows`)."""
        ...

    def last_look(self, row: LiveRow) -> str | None:
        """The newest first look in one line, for the lab's list of benches."""
        ...

    def result_tables(self, frame: ResultFrame) -> list[PageTable]:
        """result.json's tables for the run's page ([]: its declared figures instead)."""
        ...

    def result_rows(self, frame: ResultFrame) -> list[LiveRow]:
        """result.json's figures per row, unrounded, for the page's state (the station
        encodes them for /api as it does the live rows)."""
        ...


class Kind(ProcedureKind, Protocol):
    """A procedure kind with every part: the light ones (bench/core/registry.py) and those
    that report on a run, each typed (a kind's `KIND` is declared of this type)."""

    @property
    def certificate(self) -> CertificatePart:
        """Its part of the certificate."""
        ...

    @property
    def dcc(self) -> DccPart:
        """Its part of the DCC."""
        ...

    @property
    def records(self) -> RecordsPart:
        """Its figures for the records, `bench history`, the trend plot and the summary."""
        ...

    @property
    def station(self) -> StationPart:
        """Its results on the station's pages."""
        ...


# -- what a kind's `records` part may also answer: small capabilities, asked by isinstance

@runtime_checkable
class SummarisesRun(Protocol):
    """Which cells of its certificate the console summary shows (otherwise the summary
    lists the declared figures)."""

    def summary_cut(self, doc: Document) -> SummaryCut:
        """The certificate's tables and fields the console prints at the end of a run."""
        ...


#: the serial of an instrument on the stand: (axis, role, its stand-file entry) -> serial
#: (the one it reported if no other reports the same, else the stand file's, else its place)
SerialOf = Callable[[str, str, Mapping[str, YamlValue]], str]


@runtime_checkable
class ChecksInstruments(Protocol):
    """Check values of the instruments the kind measures (measurement assurance,
    docs/method.md C1), from the result and the stand file the run used; their
    quantities: key -> (unit, what the control chart calls it)."""

    check_quantities: Mapping[str, tuple[str, str]]

    def instrument_checks(self, frame: ResultFrame, stand: Mapping[str, YamlValue],
                          serial_of: SerialOf) -> list[InstrumentCheck]:
        """The check values this run gives of the instruments, per serial."""
        ...


@runtime_checkable
class HasSampleResult(Protocol):
    """A hand-made result.json of the kind, for previews of its certificate."""

    def sample_result(self) -> SampleResult:
        """A result whose printed figures are worked out by hand (its frame and the kind's
        part, typed; bench/report/codec.py `encode` gives the document)."""
        ...


@runtime_checkable
class HasStarterFiles(Protocol):
    """Commented stand and procedure files that validate, for `bench init`."""

    def starter_files(self, real: bool) -> dict[str, str]:
        """File name -> text (stand.yaml, procedure.yaml); `real`: no `sim:` block."""
        ...


# -- finding them -----------------------------------------------------------------------------

def kind_of(name: str) -> Kind:
    """The kind registered under `name`, with its every part (KeyError if none is)."""
    module, _, attr = kind_location(name).partition(":")
    kind: Kind = getattr(importlib.import_module(module), attr or "KIND")
    return kind


def installed(name: str | None) -> Kind | None:
    """The kind of that name if it is installed here, else None (a run recorded by a kind
    this installation lacks is still listed, its figures by their stored names)."""
    try:
        return kind_of(str(name)) if name else None
    except (KeyError, ImportError, AttributeError):
        return None


def installed_records(name: str | None) -> RecordsPart | None:
    """The `records` part of the kind of that name if it is installed here, else None."""
    kind = installed(name)
    return kind.records if kind is not None else None


def declared_figures(names: Sequence[str] | None = None) -> tuple[FigureSpec, ...]:
    """The figures the named kinds declare (every installed kind's when None), in the
    kinds' order, a quantity declared twice taken from the first kind."""
    out: list[FigureSpec] = []
    seen: set[str] = set()
    for name in dict.fromkeys(procedure_names() if names is None else names):
        records = installed_records(name)
        for spec in records.figures if records is not None else ():
            if spec.quantity not in seen:
                seen.add(spec.quantity)
                out.append(spec)
    return tuple(out)
