"""The item as received and as left, the decision rule's agreement, and the settings that
differ from their read-back (ISO/IEC 17025 7.1.3, 7.4, 7.8.2.1, 7.8.4.1): computed once here
for the certificate (bench/app/certificate/build.py) and the DCC's statements
(bench/app/dcc/admin.py), so both say the same.

Why: a certificate that shows only results leaves open what was calibrated when: the date
of receipt, the condition the item arrived in, whether the results are as found or as left
after an adjustment (and which run holds the other state), and whether the customer agreed
to the decision rule its verdicts use. The sources are the procedure file's optional
`item:` and `decision_rule_agreement:` blocks (bench/core/config.py) and the run's
meta.json (`bench run --as-found/--as-left --adjustment`). Nothing is invented: a part
nobody stated is printed as NOT_STATED.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from bench.core.schema import parse_date
from bench.core.settings_codec import identities
from bench.core.traceability import with_declared_serials
from bench.report.certificate.parts import Sources, stand_of
from bench.report.certificate.sources import beside
from bench.report.result_frame import Check
from drivers.json_types import JsonValue

#: what the certificate and the DCC print for a part nobody stated (the one default)
NOT_STATED = "not stated"
RULE_NAMES = {"simple": "simple acceptance (ILAC-G8:09/2019 4.2.1)",
              "guard-band": "guarded acceptance, w = U (ILAC-G8:09/2019 4.2.2)"}

#: a stand-file drive setting and the read-back that shows what the drive kept
_WATCHDOG = re.compile(r"heartbeat consumer 0x1016:1 = node (\d+), (\d+) ms")
_FACTOR = re.compile(r"0x608F = (\d+)/(\d+)")
#: why the twins' drives watch with at least 5 s (bench/core/simbench.py, stated once)
TWIN_WATCHDOG_WHY = (
    "On this simulated stand the bench raises each drive twin's heartbeat watchdog "
    "(0x1016:1) to at least 5 s by design: the twin runs in the bench's own process, so a "
    "starved host stalls both, and a shorter watchdog would stop the table for the host's "
    "pause, not for a lost controller. A real drive keeps the stand file's value.")


@dataclass(frozen=True)
class AsFound:
    """The linked as-found run: its id, whether it was found, its verdict and checks."""

    run_id: str
    found: bool
    verdict: str
    checks: tuple[Check, ...]


@dataclass(frozen=True)
class ItemRecord:
    """(label, text) rows in print order, the as-found run, the read-back differences."""

    rows: tuple[tuple[str, str], ...]
    as_found: AsFound | None
    readback: tuple[str, ...]


def _text(x: JsonValue) -> str:
    return NOT_STATED if x is None or str(x).strip() == "" else str(x).strip()


def _date(x: JsonValue) -> str:
    d = parse_date(x)
    return d.isoformat() if d is not None else _text(x)


def _as_found(src: Sources, run_id: str) -> AsFound:
    """The as-found run beside this one (the runs folder), by its run directory name."""
    found = None
    if src.run_path is not None and "/" not in run_id and run_id not in ("", ".", ".."):
        found = beside(src.run_path, run_id)
    if found is None:
        return AsFound(run_id, False, "", ())
    return AsFound(run_id, True, str(found.get("verdict") or "incomplete"), found.checks)


def decision_rule_text(src: Sources) -> str:
    """The rule the verdicts use and the customer's agreement to it (7.1.3)."""
    rule = str(src.frame.decision_rule or src.procedure_file.get("decision_rule")
               or "simple")
    agreed = src.procedure_file.get("decision_rule_agreement")
    if isinstance(agreed, Mapping) and agreed.get("agreed_with"):
        how = (f"agreed with {_text(agreed.get('agreed_with'))} on "
               f"{_date(agreed.get('agreed_on'))}"
               + (f" ({_text(agreed['reference'])})" if agreed.get("reference") else ""))
    else:
        how = f"the customer's agreement: {NOT_STATED}"
    return f"{RULE_NAMES.get(rule, rule)}; {how}"


def item_record(src: Sources) -> ItemRecord:
    """What the certificate states of the item as received and as left (17025 7.8.2.1 g,
    7.8.4.1 b): each part from the procedure file or meta.json, else NOT_STATED."""
    item = src.procedure_file.get("item")
    item = item if isinstance(item, Mapping) else {}
    state = src.meta.get("calibration_state") or src.procedure_file.get("calibration_state")
    adjustments = [str(a) for a in item.get("adjustments") or [] if str(a).strip()]
    note = src.meta.get("adjustment_note") or src.procedure_file.get("adjustment_note")
    if note and str(note) not in adjustments:
        adjustments.append(str(note))
    run_id = str(item.get("as_found_run") or "").strip()
    as_found = _as_found(src, run_id) if run_id else None
    this = src.run_path.name if src.run_path is not None else "this run"
    if as_found is not None:
        found_text = (f"run {run_id}: {as_found.verdict.upper()}, its checks below"
                      if as_found.found else
                      f"run {run_id} (not found beside this run: its results are not "
                      "restated here)")
        left_text = f"this certificate's results (run {this}, after the adjustments above)"
    elif state == "as-found":
        found_text = f"this certificate's results (run {this})"
        left_text = f"{NOT_STATED} (no as-left run links to this one yet)"
    elif state == "as-left":
        found_text = f"{NOT_STATED} (no as-found run named in item.as_found_run)"
        left_text = f"this certificate's results (run {this})"
    else:
        found_text = left_text = NOT_STATED
    rows = (("Date of receipt", _date(item.get("received"))),
            ("Condition on receipt", _text(item.get("condition"))),
            ("State of the results", {"as-found": "as found (before any adjustment)",
                                      "as-left": "as left (after adjustment)"}.get(
                                          str(state), NOT_STATED)),
            ("Adjustments made", "; ".join(adjustments) if adjustments else
             ("none (as found)" if state == "as-found" else NOT_STATED)),
            ("As-found results", found_text),
            ("As-left results", left_text),
            ("Decision rule", decision_rule_text(src)))
    return ItemRecord(rows, as_found, readback_differences(src))


def readback_differences(src: Sources) -> tuple[str, ...]:
    """Every drive setting of the stand file that differs from what the drive read back
    (the 0x1016:1 watchdog, the 0x608F counts per revolution), and why, once, on twins."""
    ids = with_declared_serials(identities(src.frame.instruments), src.stand_file)
    axes = src.stand_file.get("axes", {}) or {}
    out: list[str] = []
    for axis, roles in ids.items():
        conf = ((axes.get(axis) or {}).get("drive") or {}) if isinstance(axes, Mapping) else {}
        ident = str((roles or {}).get("drive") or "") if isinstance(roles, Mapping) else ""
        if not isinstance(conf, Mapping) or not ident:
            continue
        m = _WATCHDOG.search(ident)
        if m and conf.get("watchdog_ms") is not None and int(m[2]) != int(conf["watchdog_ms"]):
            out.append(f"axis {axis} drive: watchdog ms {conf['watchdog_ms']} in the stand "
                       f"file; the drive read back 0x1016:1 = {m[2]} ms")
        f = _FACTOR.search(ident)
        if f and conf.get("counts_per_rev") is not None and int(f[2]) > 0 \
                and int(f[1]) / int(f[2]) != float(conf["counts_per_rev"]):
            out.append(f"axis {axis} drive: counts per rev {conf['counts_per_rev']} in the "
                       f"stand file; the drive read back 0x608F = {f[1]}/{f[2]}")
    if out and any("0x1016" in line for line in out) and stand_of(src).simulated:
        out.append(TWIN_WATCHDOG_WHY)
    return tuple(out)


def statements(record: ItemRecord) -> Sequence[str]:
    """The record as plain sentences (the DCC's statements)."""
    lines = [f"{label}: {text}." for label, text in record.rows]
    if record.as_found is not None and record.as_found.found:
        for c in record.as_found.checks:
            value = next((f"{v!r} {k.removeprefix('value_')}" for k, v in c.doc.items()
                          if k.startswith("value_")), NOT_STATED)
            lines.append(f"As found (run {record.as_found.run_id}): axis {c.axis}, "
                         f"{c.quantity}"
                         + (f" at {c.set_rate_dps!r} deg/s" if c.set_rate_dps
                            is not None else "")
                         + f": value {value}, verdict {c.verdict}.")
    return lines


def setting_statements(record: ItemRecord) -> Sequence[str]:
    return [f"Setting differs from its read-back: {line}." if not line.startswith("On ")
            else line for line in record.readback]
