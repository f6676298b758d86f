"""The certificate's measurement-assurance lines, read from RUN_DIR/assurance.json.

Kept apart from assurance.py (which reads the records and so the run's certificate
number) so that the certificate can print them without an import cycle.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from bench.report.certificate.sources import read_json_object

ASSURANCE_FILE = "assurance.json"
CLAUSE = "Measurement assurance (ISO/IEC 17025 7.7)"


def certificate_notes(run_path: Path | None) -> list[str]:
    """The certificate's assurance lines, from RUN_DIR/assurance.json (build.py's hook)."""
    if run_path is None:
        return []
    doc = read_json_object(run_path / ASSURANCE_FILE)
    if not doc:
        return [f"{CLAUSE}: not assessed for this run (no records were read)."]
    if doc.get("error"):
        return [f"{CLAUSE}: NOT ASSESSED: {doc['error']}."]
    items = doc.get("instruments") or []
    if not items:
        return [f"{CLAUSE}: this run yields no check values of the bench's instruments."]
    return [f"{CLAUSE}, {i.get('line')}." for i in items if isinstance(i, Mapping)]
