"""The dwell's report parts: its certificate, its DCC, its figures for the records, and
(neutral) its station view."""

from __future__ import annotations

from collections.abc import Sequence

from lxml import etree

from bench.report.certificate.model import Para, Section, Table
from bench.report.certificate.parts import CertificateParts, Sources, num
from bench.report.dcc import units as U
from bench.report.dcc import vocab as V
from bench.report.dcc.conformity import Checks, judge
from bench.report.dcc.parts import DccParts
from bench.report.dcc.xml import el, name, quantity
from bench.report.figures import DeclaredFigures, FigureSpec, Trend
from bench.report.result_frame import Check

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
class DwellCertificate(CertificateParts):
    """Its part of the certificate: a name, its check's quantity, one section."""

    certificate_procedure_name = "dwell (a test plug-in)"
    certificate_quantities = {"dwell_time": "time waited"}

    def certificate_sections(self, src: Sources, number: str,
                             checks: Sequence[Check]) -> list[Section]:
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
