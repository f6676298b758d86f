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
HTML and DCC read the same words from here).

The analysis reads the corrections file only, never the register (docs/method.md A1, "A
counter's time-base correction").
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from bench.core import rundir_layout as layout

if TYPE_CHECKING:
    from bench.app.register.store import Register, RunRecord

#: the keys that say two corrections are the same (a re-run of a refused authorise finds
#: the run already corrected and does not analyse it again)
SAME_KEYS = ("where", "serial", "quantity", "value", "U")


def corrections_due(reg: Register, record: RunRecord) -> tuple[list[dict[str, object]],
                                                                  list[str]]:
    """(the corrections the register's as-found errors call for on this run, the reasons
    not to issue): each of the run's items whose latest finding's span holds the run's
    registration day. An item found out of tolerance for which no correction is modelled
    refuses: the figures it moved would be issued as if nothing were known."""
    from bench.app.impact import correction_entry, finding_of, touched
    from bench.app.register.store import RegisterError

    due: list[dict[str, object]] = []
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
        entry = correction_entry(finding, where)
        if entry is None:
            if finding.found == "out":
                refused.append(f"item {serial} ({where}) was found out of tolerance "
                               f"(calibration {finding.certificate}) and this run used it; "
                               "no correction model exists for it yet, so the issue would "
                               "state figures the finding moves (docs/register.md, bench "
                               "impact)")
            continue
        if entry.get("U") is None:
            refused.append(f"item {serial} ({where}): the as-found error {finding.error:g} "
                           "has no U: a correction without its uncertainty cannot enter the "
                           "budget (bench register equipment update SERIAL --found-error "
                           "V,U)")
            continue
        due.append(entry)
    return due, refused


def _key(c: Mapping[str, object]) -> tuple[object, ...]:
    return tuple(c.get(k) for k in SAME_KEYS)


def already_applied(result: Mapping[str, object], due: Sequence[Mapping[str, object]]
                    ) -> bool:
    """Whether the registered result states exactly these corrections."""
    stated = result.get("corrections")
    have = sorted((_key(c) for c in stated if isinstance(c, Mapping)), key=repr) \
        if isinstance(stated, list) else []
    return have == sorted((_key(c) for c in due), key=repr)


def write_corrections(run_path: Path, due: Sequence[Mapping[str, object]],
                      reason: str | None) -> Path:
    """The run folder's corrections file: each correction with why it is applied."""
    from bench.app.impact import CORRECTIONS_FILE

    path = Path(run_path) / CORRECTIONS_FILE
    doc = {"corrections": [{**c, "reason": (reason or "").strip() or None} for c in due]}
    path.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
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


def _g(x: object) -> str:
    return f"{x:.3g}" if isinstance(x, int | float) and math.isfinite(x) else "not stated"


def statements(result: Mapping[str, object]) -> list[str]:
    """The certificate's words for each correction the result applied (PDF, HTML and DCC
    alike): the item, e with its U, what was done with it and why."""
    out = []
    stated = result.get("corrections")
    for c in stated if isinstance(stated, list) else []:
        if not isinstance(c, Mapping):
            continue
        where = str(c.get("where") or "?")
        what = (f"the counter at {where} ({c.get('model') or 'model not stated'}, serial "
                f"{c.get('serial') or 'not stated'})")
        if c.get("quantity") == "timebase_offset_rel":
            done = ("every interval it timed was divided by 1 + e before the analysis, which "
                    "moves each rate error by about +e and the FOG scale k by about -e k; "
                    "u(e) = U/2 is a row of the rate error's uncertainty budget "
                    "(docs/method.md A1, a counter's time-base correction)")
            value = f"time-base offset e = {_g(c.get('value'))} (U = {_g(c.get('U'))}, k = 2)"
        else:
            done = "applied as the analysis states in result.json's corrections"
            value = f"{c.get('quantity')} = {_g(c.get('value'))} (U = {_g(c.get('U'))})"
        text = (f"Correction applied: {what} had a {value}"
                + (f", the {c.get('source')}" if c.get("source") else "") + f"; {done}.")
        if c.get("reason"):
            text += f" Why: {c.get('reason')}."
        out.append(text)
    return out
