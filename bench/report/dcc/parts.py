"""What the DCC asks a procedure kind, with neutral answers (the DCC's `CertificateParts`).

The DCC writer (writer.py) writes what every DCC has (administrative data, the method
document, the GUM statement, instruments, conditions, the checks left over) and asks the
procedure kind for the rest through `DccParts`: a kind's `dcc` part is a subclass of it (its
`certificate` part a `bench.report.certificate.parts.CertificateParts`) that overrides what it has to say. It builds its
measurementResults from the DCC's vocabulary: `bench.report.dcc.xml` (elements, quantities,
lists, budgets), `bench.report.dcc.units` (D-SI units), `bench.report.dcc.vocab` (refTypes; a kind's
own terms are `vocab.RB + "name"`, defined in docs/dcc.md) and `bench.report.dcc.conformity`
(`Checks.take` and `judge` put each check on the quantity it judges). A kind that says
nothing still gets a valid DCC: its results are then "No results", pointing to result.json.
Nothing here names a procedure.
"""

from __future__ import annotations

from collections.abc import Sequence

from lxml import etree

from bench.report.certificate.parts import Sources
from bench.report.dcc.conformity import Checks


class DccParts:
    """The DCC's questions to a procedure kind, with neutral answers."""

    def dcc_item(self, src: Sources) -> tuple[str, Sequence[str]]:
        """(the item calibrated in words, its axes) for the DCC's items/item."""
        return "test stand", ()

    def dcc_used_methods(self, src: Sources) -> tuple[str, Sequence[str]]:
        """(what the method is, for the embedded method document; the sections of
        docs/method.md the kind follows, e.g. ("A1", "A2"), each a usedMethod)."""
        return ("The bench's method document as shipped; this procedure kind names no "
                "section of it as its method."), ()

    def dcc_results(self, results: etree._Element, src: Sources, checks: Checks) -> None:
        """Append the kind's measurementResult(s) to `results` (dcc:measurementResults),
        taking each check it judges from `checks`; the checks left over become statements."""
