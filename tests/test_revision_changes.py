"""Issue 43: a re-issue's "what changed" compares every statement of the two revisions (their
HTML as rendered: assurance, traceability, conformity text), not only result.json; the
result digest the certificate states is the SHA-256 of result.json as stored.

Truth is hand-made: two small certificates that differ in one assurance note (run 9's R2
said "results unchanged" although its assurance statement changed), and the bytes of a
result.json written by hand.
"""

from __future__ import annotations

import hashlib
import json

from bench.app.certificate import result_digest
from bench.app.certificate.authorise import changes_between
from bench.app.certificate.html import render_html
from bench.app.certificate.revisions import statements
from bench.report.certificate.model import Document, Fields, Para, Section, Table

RESULT = b'{"verdict": "pass", "axes": {"outer": {"rates": [{"rate_error_rel": 1e-7}]}}}'
BASELINE = "Measurement assurance (ISO/IEC 17025 7.7), counter MY62000117: {}."


def _html(revision: str, assurance: str, signed_at: str) -> str:
    """A certificate of three sections as the renderer writes it."""
    doc = Document("RT-2026-00009" + revision, "Calibration certificate", "a table", "Lab",
                   "2026-11-27", "pass", (
                       Section("1", "Identification", (Fields((
                           ("Certificate number", "RT-2026-00009" + revision),
                           ("Revision", revision or "1 (first issue)"),
                           ("Customer", "Demo customer"))),)),
                       Section("2", "Item calibrated and measuring instruments", (
                           Table(("Item", "Serial", "Status"),
                                 (("counter", "MY62000117", "valid on the work's date"),),
                                 caption="Metrological traceability",
                                 notes=(BASELINE.format(assurance),)),
                           Para("Decision rule: simple acceptance."))),
                       Section("3", "Authorisation", (Para(f"Signed {signed_at}"),))),
                   "footer", meta={"run_title": "t", "revision": revision, "replaces": "",
                                   "scope": "s"})
    return render_html(doc)


def test_statements_are_read_from_the_html_without_the_revision_s_own_lines() -> None:
    said = statements(_html("", "in control", "10:00"))
    assert ("Identification", "Customer: Demo customer") in said
    assert ("Item calibrated and measuring instruments",
            "counter | MY62000117 | valid on the work's date") in said
    assert ("Item calibrated and measuring instruments",
            BASELINE.format("in control")) in said
    assert not [s for s in said if s[1].startswith(("Certificate number", "Revision"))
                or s[0] == "Authorisation"]


def test_a_changed_assurance_statement_is_a_change_though_results_are_equal() -> None:
    r1 = _html("", "not enough history (1 of 8 runs for a baseline)", "10:00")
    r2 = _html("-R2", "OUT OF CONTROL (rule 1 at run 9)", "11:00")
    assert changes_between(RESULT, RESULT, r1, r2) == (
        "Item calibrated and measuring instruments: '"
        + BASELINE.format("not enough history (1 of 8 runs for a baseline)") + "' -> '"
        + BASELINE.format("OUT OF CONTROL (rule 1 at run 9)") + "'",)
    same = changes_between(RESULT, RESULT, r1, _html("-R2", "not enough history (1 of 8 "
                                                            "runs for a baseline)", "11:00"))
    assert same == ("results unchanged (result.json equal to the replaced revision's); every "
                    "statement unchanged (the replaced revision's certificate.html compared)",)
    # the replaced revision's HTML not kept: said so, not "unchanged"
    assert changes_between(RESULT, RESULT, None, r2) == (
        "the replaced revision's certificate.html is not kept; its statements are not "
        "compared",)


def test_the_result_digest_is_of_the_file_as_stored() -> None:
    stored = json.dumps({"verdict": "pass", "axes": {}}, indent=2).encode()  # not canonical
    assert result_digest(stored) == hashlib.sha256(stored).hexdigest()
    canonical = json.dumps(json.loads(stored), sort_keys=True).encode()
    assert result_digest(stored) != hashlib.sha256(canonical).hexdigest()
