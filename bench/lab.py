"""The laboratory's own settings: who issues the certificates, where, and who signs them.

A procedure names them with `certificate: {lab: ../lab.yaml}` (relative to the procedure
file); its own `certificate:` keys override the lab file's. They are resolved once, when
the run starts, into result.json's `certificate` block, so a certificate re-issued later
shows who was authorised when the work was done.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from bench.schema import Bool, Key, ListOf, Map, Str, validate
from bench.yamlfile import Problem, YamlDoc, YamlError, load_yaml

SIGNATORY = Map({
    "name": Key(Str(), True, "the person's name, printed under the signature line"),
    "function": Key(Str(), True, "their function in the laboratory"),
    "authorises": Key(Bool(), False, "true for the signatory who authorises the issue"),
})
LAB = Map({
    "laboratory": Key(Str(), True, "the laboratory's name, on every page"),
    "address": Key(Str(), True, "the laboratory's address (ISO/IEC 17025 7.8.2.1 b)"),
    "accreditation": Key(Str(), False, "accreditation body and number, or 'not accredited'"),
    "site": Key(Str(), False, "where calibrations are performed, when not at the address"),
    "prefix": Key(Str(), False, "prefix of generated certificate numbers (default RT)"),
    "signatories": Key(ListOf(SIGNATORY, min_len=1), True,
                       "named signatories with their functions"),
    "authoritative": Key(Str(("pdf",)), False, "the authoritative form (pdf)"),
})


RUN_COPY = "lab.yaml"  # the lab file as used, copied into the run directory


def lab_path(procedure_path: Path, certificate: Any) -> Path | None:
    """The lab file a procedure names; in a run directory, the copy made when it started."""
    ref = certificate.get("lab") if isinstance(certificate, dict) else None
    if not isinstance(ref, str):
        return None
    here = procedure_path.parent
    if (here / "meta.json").is_file():  # a run directory: its copy, if one was made
        return here / RUN_COPY if (here / RUN_COPY).is_file() else None
    p = Path(ref)
    return p if p.is_absolute() else Path(os.path.normpath(procedure_path.parent / p))


def lab_problems(procedure_path: Path, procedure_doc: YamlDoc,
                 certificate: Any) -> list[Problem]:
    """The lab file named by `certificate.lab`: it exists and its keys are known."""
    path = lab_path(procedure_path, certificate)
    if path is None:
        if isinstance(certificate, dict) and not isinstance(certificate.get("lab", ""), str):
            return [procedure_doc.problem(("certificate", "lab"),
                                          "expected the path of a lab settings file")]
        return []
    try:
        doc = load_yaml(path)
    except YamlError as e:
        if e.problem.key == "(file)":
            return [procedure_doc.problem(("certificate", "lab"),
                                          f"lab settings file {path}: {e.problem.message}")]
        return [e.problem]
    return validate(doc, LAB)


def certificate_settings(procedure_path: Path, certificate: Any) -> dict[str, Any]:
    """The lab file's keys under the procedure's own `certificate:` keys."""
    own = dict(certificate) if isinstance(certificate, dict) else {}
    path = lab_path(procedure_path, own)
    if path is None:
        return own
    lab = load_yaml(path).data
    merged = {**(lab if isinstance(lab, dict) else {}), **own}
    merged["lab"] = path.name
    return merged
