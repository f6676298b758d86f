"""Write a run's DCC: build it, sign it when the lab configured a key, validate, write.

The XML is validated offline against the shipped schemas before it is written; one that
does not validate is kept as certificate.dcc.invalid.xml for diagnosis, never under the
real name, and a stale certificate.dcc.xml from an earlier analysis is removed.
"""

from __future__ import annotations

import datetime as dt
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from lxml import etree

from bench.app.certificate.register import Issue
from bench.app.dcc import DCC_NAME, INVALID_NAME
from bench.app.dcc.settings import SettingsError, check_key_outside, resolve_settings
from bench.app.dcc.validate import Validation, describe, validate_dcc
from bench.app.dcc.writer import DccInputs, build_dcc
from bench.core.config import DccRefs
from bench.core.lab import Lab, run_lab
from bench.core.settings_codec import lab_keys
from bench.report.certificate.sources import Sources

VERDICTS = ("pass", "fail")

__all__ = ["DccOutcome", "SettingsError", "dcc_bytes", "write_dcc"]


@dataclass(frozen=True)
class DccOutcome:
    """What happened: the file written (or None), its validation, whether it is signed."""

    path: Path | None
    validation: Validation | None
    signed: bool = False
    skipped: str = ""       # why no DCC was written (an incomplete run)

    @property
    def ok(self) -> bool:
        return self.path is not None and self.validation is not None and self.validation.valid

    def message(self) -> str:
        if self.skipped:
            return f"no {DCC_NAME}: {self.skipped}"
        assert self.validation is not None
        where = self.path or INVALID_NAME
        return describe(self.validation, where) + (" (signed, XAdES)" if self.signed else "")


def dcc_bytes(tree: etree._ElementTree, pretty: bool = True) -> bytes:
    data: bytes = etree.tostring(tree, xml_declaration=True, encoding="UTF-8",
                                 pretty_print=pretty)
    return data


def _write_atomic(path: Path, data: bytes) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def write_dcc(run_path: Path, src: Sources,
              stand: DccRefs | None = None,
              lab_file: str | Path | None = None, issued: dt.date | None = None,
              lab: Lab | None = None, issue: Issue | None = None,
              out_dir: Path | None = None,
              signer: Callable[[bytes], bytes] | None = None) -> DccOutcome:
    """Build, validate and write the DCC: the draft (never signed: nobody authorised
    it), or the `issue` being authorised, signed when the lab configured a key.

    A run without a verdict (incomplete) gets no DCC: it certifies nothing. Raises
    SettingsError when the lab's settings or key are unusable. `out_dir` (default the
    run directory) is where it goes; the embedded PDF is the one there.
    """
    run_path = Path(run_path)
    out = Path(out_dir) if out_dir is not None else run_path
    frame = src.frame
    verdict = (frame.verdict or "incomplete").lower()
    if verdict not in VERDICTS:
        (out / DCC_NAME).unlink(missing_ok=True)   # it would stand for other results
        return DccOutcome(None, None, skipped=f"the run's verdict is {verdict!r}; a DCC is "
                                                "written only for a completed run")
    settings = lab if lab is not None else resolve_settings(
        stand, lab_file, base=run_lab(run_path, lab_keys(frame.certificate)))
    data = dcc_bytes(build_dcc(DccInputs(src, settings, issued, issue=issue, pdf_dir=out)))
    signed = False
    if signer is not None and issue is not None and not issue.draft:
        data = signer(data)         # the lab's register service holds the key (issue 53)
        signed = True
    elif settings.signing is not None and issue is not None and not issue.draft:
        from bench.app.dcc.signing import sign_tree

        check_key_outside(settings.signing, run_path)
        # laid out first, then signed and written as is: re-indenting would change the
        # signed bytes' whitespace and break the signature
        parser = etree.XMLParser(huge_tree=True, no_network=True, resolve_entities=False)
        signed_tree = sign_tree(etree.ElementTree(etree.fromstring(data, parser)),
                                settings.signing)
        data = dcc_bytes(signed_tree, pretty=False)
        signed = True
    validation = validate_dcc(data)
    target, other = out / DCC_NAME, out / INVALID_NAME
    if validation.valid:
        _write_atomic(target, data)
        other.unlink(missing_ok=True)
        return DccOutcome(target, validation, signed)
    _write_atomic(other, data)
    target.unlink(missing_ok=True)    # a stale valid DCC must not stand for these results
    return DccOutcome(None, validation, signed)
