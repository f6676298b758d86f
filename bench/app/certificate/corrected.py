"""The corrected re-issue (issue 58): a run touched by an item's as-found error is issued
again from a new registered analysis of its raw captures with the correction applied.

ISO/IEC 17025 7.10 and 6.4.13: when a standard comes back from its own calibration out of
tolerance, the certificates issued with it are assessed (`bench impact SERIAL`) and, where
a figure moved, re-issued. `bench authorise RUN --reason TEXT` does the second step: it
asks the register which of the run's items carry an as-found error whose span touches the
run (bench/app/impact.py: since the last calibration found in tolerance, up to the one
with the finding), writes the corrections file (`corrections.json`) into the run folder,
analyses the run again as `bench analyze RUN --reason` does (the register records the new
result: op deliver_result, audit "run analysis result"), and issues from that registered
result. The result states the corrections it applied (`corrections`: the item, its serial,
e with its U, where it came from, why), and the certificate says so in every form (PDF,
HTML and DCC read the same words: bench/report/corrections.py).

The analysis reads the corrections file only, never the register (docs/method.md A1, "A
counter's time-base correction").
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from bench.core import rundir_layout as layout

if TYPE_CHECKING:
    from bench.app.impact_codec import CorrectionEntry
    from bench.app.register.store import Register, RunRecord


def corrections_due(reg: Register, record: RunRecord) -> tuple[list[CorrectionEntry],
                                                                  list[str]]:
    """(the corrections the register's as-found errors call for on this run, the reasons
    not to issue): each of the run's items whose latest finding's span holds the run's
    registration day. An item found out of tolerance for which no correction is modelled
    refuses: the figures it moved would be issued as if nothing were known."""
    from bench.app.impact import correction_entry, finding_of, touched
    from bench.app.register.store import RegisterError

    due: list[CorrectionEntry] = []
    refused: list[str] = []
    for item in record.items:
        serial, where = item.get("serial"), str(item.get("where") or "?")
        if not serial:
            continue
        held = next(iter(reg.equipment(str(serial))), None)
        if held is None:
            continue
        try:
            finding = finding_of(held)
        except RegisterError:
            continue                      # no as-found error recorded: nothing to correct
        if not touched([record], finding):
            continue
        corr = correction_entry(finding, where)
        if corr is None:
            if finding.found == "out":
                refused.append(f"item {serial} ({where}) was found out of tolerance "
                               f"(calibration {finding.certificate}) and this run used it; "
                               "no correction model exists for it yet, so the issue would "
                               "state figures the finding moves (docs/register.md, bench "
                               "impact)")
            continue
        if corr.U is None:
            refused.append(f"item {serial} ({where}): the as-found error {finding.error:g} "
                           "has no U: a correction without its uncertainty cannot enter the "
                           "budget (bench register equipment update SERIAL --found-error "
                           "V,U)")
            continue
        due.append(corr)
    return due, refused


def already_applied(result: str | None, due: Sequence[CorrectionEntry]) -> bool:
    """Whether the registered result (its result.json text, None: none registered) states
    exactly these corrections."""
    from bench.app.impact_codec import json_tree
    from bench.report.corrections import Correction
    from bench.report.result_frame import corrections_of

    have = corrections_of(json_tree(result or "{}"))
    want = [Correction(d.where, d.serial, d.model, d.quantity, d.value, d.U, d.source, None)
            for d in due]
    return len(have) == len(want) and all(any(h.same_as(w) for h in have) for w in want) \
        and all(any(w.same_as(h) for w in want) for h in have)


def write_corrections(run_path: Path, due: Sequence[CorrectionEntry],
                      reason: str | None) -> Path:
    """The run folder's corrections file: each correction with why it is applied."""
    from bench.app.impact import CORRECTIONS_FILE
    from bench.app.impact_codec import encode_reasoned_corrections

    path = Path(run_path) / CORRECTIONS_FILE
    path.write_text(encode_reasoned_corrections(due, (reason or "").strip() or None),
                    encoding="utf-8")
    return path


def analyse_corrected(run_path: Path, reason: str) -> tuple[bool, str]:
    """`bench analyze RUN --reason REASON` in a process of its own (the one path that makes
    a registered analysis: result.json, the draft certificate, the records, the register's
    "run analysis result"); (done, why not)."""
    done = subprocess.run([sys.executable, "-m", "bench", "analyze", str(run_path),
                           "--reason", reason, "--quiet"],
                          capture_output=True, text=True, env=dict(os.environ), timeout=3600)
    if done.returncode not in (0, 1):
        why = (done.stderr.strip().splitlines() or [f"exit {done.returncode}"])[-1]
        return False, why
    return True, ""


def registered_again(reg: Register, uid: str, run_path: Path) -> RunRecord | None:
    """The register's record once it holds the run folder's new result.json (None: it
    does not: the analysis was not delivered)."""
    rec = reg.run_record(uid)
    result = Path(run_path) / layout.RESULT
    if rec is None or not result.is_file():
        return None
    return rec if hashlib.sha256(result.read_bytes()).hexdigest() == rec.result_sha256 \
        else None
