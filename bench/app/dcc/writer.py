"""result.json (plus the run directory) -> a PTB DCC 3.3.0 document (lxml tree).

Every number comes from result.json unrounded (see bench.report.dcc.xml.dec); what the result
lacks comes from the run directory's records or the laboratory's settings, never invented.
A required DCC field nobody recorded says "not recorded" in its text, so the gap shows.
Layout (docs/dcc.md walks through it):

    administrativeData   software, refTypeDefinitions, core data (ids, dates, location),
                         the item with its serial, laboratory, responsible persons,
                         customer, statements (decision rule and overall conformity,
                         location, raw-data SHA-256 digests, simulated stand)
    measurementResults   methods (docs/method.md sections), conditions, then the
                         procedure kind's measurementResults (its `dcc_results`,
                         bench.report.dcc.parts.DccParts); each check's conformity sits on
                         the quantity it judges
    document             certificate.pdf, the human-readable certificate
"""

from __future__ import annotations

import base64
import datetime as dt
from dataclasses import dataclass
from pathlib import Path

from lxml import etree

from bench.app.certificate import register
from bench.app.certificate.build import Sources, certificate_id, procedure_of
from bench.app.dcc.admin import administrative
from bench.app.dcc.used_methods import methods_and_conditions
from bench.app.dcc.validate import SCHEMA_LOCATION
from bench.core import rundir_layout as layout
from bench.core.lab import Lab, run_lab
from bench.core.settings_codec import lab_keys
from bench.kind import installed
from bench.report.budget_codec import budget_sites
from bench.report.dcc.budgets import budget_results
from bench.report.dcc.conformity import Checks, checks_of, leftover_checks
from bench.report.dcc.parts import DccParts
from bench.report.dcc.xml import DCC_NS, XSI_NS, el, name, text_el

PDF_NAME = layout.CERTIFICATE_PDF
#: what a procedure kind that says nothing of itself in the DCC (or none installed) answers
NEUTRAL = DccParts()


@dataclass(frozen=True)
class DccInputs:
    """What the writer reads: the run decoded (result.json and its run directory,
    `Sources.load`), the lab's settings (None: the run's own, bench.core.lab.run_lab), and
    the issue (None: the draft of the next one)."""

    src: Sources
    lab: Lab | None = None
    issued: dt.date | None = None
    embed_pdf: bool = True
    issue: register.Issue | None = None
    pdf_dir: Path | None = None     # where certificate.pdf is (default the run directory)


def build_dcc(inputs: DccInputs) -> etree._ElementTree:
    """The DCC as an lxml tree (unsigned); `bench.app.dcc.validate` checks it."""
    src = inputs.src
    proc = procedure_of(src)        # the kind, found as the certificate finds it
    found = installed(proc.name)
    kind = found.dcc if found is not None else NEUTRAL
    checks = Checks(checks_of(src))
    root = el(None, "digitalCalibrationCertificate", schemaVersion="3.3.0")
    root.set(f"{{{XSI_NS}}}schemaLocation", SCHEMA_LOCATION)
    today = (inputs.issued or dt.datetime.now(dt.UTC).date()).isoformat()
    issue = inputs.issue or register.draft(src.run_path, certificate_id(src))
    lab = inputs.lab
    if lab is None:
        lab = run_lab(src.run_path, lab_keys(src.frame.certificate)) if src.run_path else Lab()
    administrative(el(root, "administrativeData"), src, lab, proc.parts, kind, issue, today)
    results = el(root, "measurementResults")
    methods_and_conditions(results, src, kind)
    kind.dcc_results(results, src, checks)
    budget_results(results, budget_sites(src.walked))
    if results.find(f"{{{DCC_NS}}}measurementResult") is None:    # the DCC needs one
        mr = el(results, "measurementResult", id="noResults")
        name(mr, "No results")
        r = el(el(mr, "results"), "result")
        name(r, "No results")
        text_el(el(r, "data"), "text", "result.json carries no results: nothing was measured "
                "to completion, or its results were malformed.")
    leftover_checks(root, src, checks)
    where = inputs.pdf_dir or src.run_path
    pdf = where / PDF_NAME if where is not None else None
    if inputs.embed_pdf and pdf is not None and pdf.is_file():
        doc = el(root, "document", id="certificatePdf")
        name(doc, "Calibration certificate, human-readable (PDF, same content)")
        el(doc, "fileName", PDF_NAME)
        el(doc, "mimeType", "application/pdf")
        el(doc, "dataBase64", base64.b64encode(pdf.read_bytes()).decode("ascii"))
    return etree.ElementTree(root)
