"""result.json (plus the run directory) -> the certificate's document model.

Every figure printed is taken from result.json; what the result lacks is taken from the
run directory's own records (meta.json, the copied stand and procedure files, the event
log, the raw files themselves) and never invented. Anything neither has is printed as
"not recorded", so a gap is visible to the reader instead of silently filled.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

import bench
from bench.analysis.random_part import std_u_rel
from bench.certificate import methods, plots, register
from bench.certificate.model import Document, Fields, Figure, Para, Section, Signatures, Table
from bench.certificate.operator import prompt_blocks, software_note
from bench.certificate.register import Issue
from bench.certificate.rounding import (
    MINUS,
    PERCENT,
    PPM,
    RESOLUTION_RULE,
    Presented,
    RelUnit,
    format_limit,
    format_sig,
    format_value_u,
    is_resolved,
    present,
    present_phase,
    rel_unit,
)
from bench.certificate.shape import conform_result
from bench.journal import read_jsonl, sha256_file
from bench.traceability import MEASURING_ROLES, traced_items

NOT_RECORDED = "not recorded"
CAPABILITY_LIMIT = 0.3  # RMG 63-2003: the measurement's error limit <= 0.2-0.3 of the tolerance
QUANTITY_NAMES = {
    "rate_error": "per-turn rate error |δ|",
    "rate_instability": "per-turn rate instability σ",
    "intra_turn_instability": "intra-turn instability",
    "intra_turn_instability_corrected": "intra-turn instability, floor-corrected",
    "own_drift": "own drift",
    "apparent_drift": "apparent drift",
    "earth_horizontal_rate": "horizontal Earth rate",
    "azimuth": "platform azimuth",
}


# -- the inputs ----------------------------------------------------------------------------

@dataclass
class Sources:
    """result.json and whatever the run directory adds to it."""

    result: dict[str, Any]
    run_path: Path | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    stand_file: dict[str, Any] = field(default_factory=dict)
    procedure_file: dict[str, Any] = field(default_factory=dict)
    events: list[dict[str, Any]] = field(default_factory=list)
    dropped: list[str] = field(default_factory=list)  # malformed parts of result.json

    @classmethod
    def load(cls, result: dict[str, Any], run_path: Path | None) -> Sources:
        conformed, dropped = conform_result(result)
        src = cls(conformed, run_path, dropped=dropped)
        if run_path is None:
            return src
        src.meta = _read_json(run_path / "meta.json")
        src.stand_file = _read_yaml(run_path / "stand.yaml")
        src.procedure_file = _read_yaml(run_path / "procedure.yaml")
        events = run_path / "events.jsonl"
        if events.exists():
            src.events = list(read_jsonl(events))
        return src

    def get(self, key: str, default: Any = None) -> Any:
        value = self.result.get(key)
        return default if value is None else value


def _read_json(path: Path) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _read_yaml(path: Path) -> dict[str, Any]:
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError):
        return {}
    return data if isinstance(data, dict) else {}


def _num(x: Any) -> float | None:
    if isinstance(x, bool) or x is None:
        return None
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def _utc(stamp: str | None) -> str:
    if not stamp:
        return NOT_RECORDED
    try:
        t = dt.datetime.fromisoformat(str(stamp).replace("Z", "+00:00"))
    except ValueError:
        return str(stamp)
    if t.tzinfo is not None:
        t = t.astimezone(dt.UTC)
    return t.strftime("%Y-%m-%d %H:%M:%S UTC")


UNIT_SUFFIXES = {"c": "°C", "deg": "°", "pct": "%", "hpa": "hPa", "hz": "Hz", "s": "s",
                 "dps": "°/s", "dph": "°/h", "dps2": "°/s²", "v": "V", "rel": "fraction"}


def _label(key: str) -> str:
    """`static_record_s` -> 'Static record, s'."""
    words = str(key).split("_")
    unit = UNIT_SUFFIXES.get(words[-1].lower()) if len(words) > 1 else None
    text = " ".join(words[:-1] if unit else words)
    text = text[:1].upper() + text[1:]
    return f"{text}, {unit}" if unit else text


def _text(value: Any) -> str:
    if value is None or value == "":
        return NOT_RECORDED
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, list | tuple):
        return ", ".join(_text(v) for v in value)
    if isinstance(value, dict):
        return "; ".join(_key_value(k, v) for k, v in value.items())
    return str(value).replace("+/-", "±")


def _key_value(key: str, value: Any) -> str:
    """`max_rate_dps: 400` -> 'max rate: 400 °/s'."""
    words = str(key).split("_")
    unit = UNIT_SUFFIXES.get(words[-1].lower()) if len(words) > 1 else None
    if unit and unit != "fraction":
        return f"{' '.join(words[:-1])}: {_text(value)} {unit}"
    return f"{' '.join(words)}: {_text(value)}"


def _trim(x: float) -> str:
    """A stated limit as written (1e-5 -> '0.00001'), no invented trailing zeros."""
    s = format_sig(x, 6)
    return s.rstrip("0").rstrip(".") if "." in s and "e" not in s else s


def _rate(x: Any) -> str:
    v = _num(x)
    if v is None:
        return NOT_RECORDED
    return f"{v:+g}".replace("-", MINUS)


def verdict_label(verdict: Any, rule: str | None = None, inside_tolerance: bool = False) -> str:
    """How a verdict is printed; a guard-band refusal says so."""
    v = str(verdict or "").strip().lower()
    if v == "pass":
        return "PASS"
    if v in ("conditional", "conditional-pass"):
        return "CONDITIONAL"
    if v in ("fail-guard-band", "guard-band", "not-passed"):
        return "FAIL (guard band)"
    if v == "fail":
        return "FAIL (guard band)" if rule == "guard-band" and inside_tolerance else "FAIL"
    if v == "incomplete":
        return "INCOMPLETE"
    if v == "not-assessed":
        return "NOT ASSESSED"
    return v.upper() or "—"


# -- the certificate id ----------------------------------------------------------------

def certificate_id(src: Sources) -> str:
    """The base number of the run's certificates: the laboratory's own if the procedure
    gives one, else `<prefix>-<date of completion>-<8 hex digits>`.

    The digits identify the run (its directory and creation time), so two runs never share
    a number; each issue of one run adds its revision (register.numbered). Without a run
    (a specimen) the digits are a digest of the results.
    """
    cert = _cert(src)
    for key in ("number", "id", "certificate_id"):
        if cert.get(key):
            return str(cert[key])
    run_dir = src.get("run_dir") or (src.run_path.name if src.run_path else None)
    created = (src.get("dates", {}) or {}).get("created_utc") or src.meta.get("created_utc")
    identity = (f"{run_dir}|{created}" if run_dir else
                json.dumps(src.result, sort_keys=True, default=str))
    digest = hashlib.sha256(identity.encode())
    stamp = (src.get("dates", {}) or {}).get("completed_utc") or src.meta.get("created_utc")
    day = ""
    if stamp:
        try:
            day = dt.datetime.fromisoformat(str(stamp).replace("Z", "+00:00")).strftime("%Y%m%d")
        except ValueError:
            day = ""
    prefix = cert.get("prefix", "RT")
    return "-".join(p for p in (str(prefix), day, digest.hexdigest()[:8].upper()) if p)


def issued_number(src: Sources) -> str:
    """The number of the run's latest issue (what the PDF beside it carries); the base
    number when nothing was issued yet. For other forms of the same certificate (DCC)."""
    done = register.issues(src.run_path)
    return done[-1].number if done else certificate_id(src)


def _cert(src: Sources) -> dict[str, Any]:
    """The certificate settings: the procedure's `certificate:` block over the lab's file."""
    cert = src.get("certificate", {}) or src.procedure_file.get("certificate", {}) or {}
    return dict(cert) if isinstance(cert, Mapping) else {}


# -- the document --------------------------------------------------------------------------

AUTHORITATIVE = ("The PDF file certificate.pdf is the authoritative form of this certificate; "
                 "the HTML rendering carries the same content for reading on screen.")
SIMULATED_MARK = "SIMULATED RUN: NOT A CALIBRATION"


#: a section from outside the run directory (the records' history): title and blocks
ExtraSection = tuple[str, tuple[Any, ...]]


def build_document(result: dict[str, Any], run_path: Path | None = None,
                   issued: dt.date | None = None, issue: Issue | None = None,
                   extra_sections: Sequence[ExtraSection] = ()) -> Document:
    """The certificate for one issue. Without `issue` it is the run's next one (revision 1
    when nothing was issued yet), dated today or `issued`, and nothing is recorded."""
    src = Sources.load(result, run_path)
    cid = certificate_id(src)
    if issue is None:
        when = (dt.datetime.combine(issued, dt.time(12), dt.UTC) if issued
                else dt.datetime.now(dt.UTC))
        issue = register.next_issue(run_path, cid, when)
    kind = src.get("procedure") or src.procedure_file.get("procedure") or (
        "drift-pulse" if src.get("drift") else "rate-ladder")
    cert = _cert(src)
    lab = str(cert.get("laboratory") or "Calibration laboratory (name not given)")
    checks = _checks(src)
    sections: list[Section] = []
    n = _Counter()
    sections.append(Section(n.next(), "Identification", _identification(src, issue,
                                                                       kind, checks)))
    sections.append(Section(n.next(), "Item calibrated and measuring instruments",
                            _instruments(src, kind)))
    sections.append(Section(n.next(), "Method", _method(src, kind)))
    sections.append(Section(n.next(), "Deviations", _deviations(src, kind)))
    sections.append(Section(n.next(), "Conditions", _conditions(src)))
    results_no = n.next()
    if kind == "drift-pulse":
        sections += _drift_results(src, results_no)
    else:
        sections += _ladder_results(src, results_no, checks)
    sections.append(Section(n.next(), "Conformity", _conformity(src, checks)))
    sections.append(Section(n.next(), "Records: raw data and inputs", _records(src)))
    if kind != "drift-pulse" and any(r.get("counter_rate_dps") for r in _all_rates(src)):
        sections.append(Section(n.next(), "Per-turn counter rates", _per_turn_annex(src)))
    for title, blocks in extra_sections:
        sections.append(Section(n.next(), title, tuple(blocks)))
    statements = [t for t in methods.STATEMENTS
                  if kind != "drift-pulse" or not t.startswith("Relative values")]
    statements.append(AUTHORITATIVE)
    sections.append(Section(n.next(), "Statements", tuple(Para(t) for t in statements)))
    sections.append(Section(n.next(), "Authorisation", _signatures(cert, issue)))
    item, serial = _item(src, kind)
    subtitle = f"{item}, serial {serial}"
    simulated = bool(_stand(src).get("simulated"))
    if simulated:
        subtitle += " (SIMULATED stand)"
    return Document(
        cert_id=issue.number,
        title="Calibration certificate",
        subtitle=subtitle,
        laboratory=lab,
        issue_date=issue.issue_date,
        verdict=str(src.get("verdict", "incomplete")),
        sections=tuple(sections),
        footer="This certificate shall not be reproduced except in full without the written "
               "approval of the issuing laboratory. " + AUTHORITATIVE.split(";")[0] + ".",
        meta={"run_title": str(src.get("title") or src.procedure_file.get("title") or ""),
              "procedure": kind, "revision": str(issue.revision),
              "replaces": issue.replaces or "", "scope": _scope_line(src, checks, kind)},
        watermark=SIMULATED_MARK if simulated else "",
    )


class _Counter:
    def __init__(self) -> None:
        self.i = 0

    def next(self) -> str:
        self.i += 1
        return str(self.i)


def _checks(src: Sources) -> list[dict[str, Any]]:
    """The engine's checks[]; without it, the per-rate judgements of the analysis."""
    if isinstance(src.result.get("checks"), list):
        return [c for c in src.result["checks"] if isinstance(c, dict)]
    out = []
    for axis, ax in (src.get("axes", {}) or {}).items():
        for r in ax.get("rates", []):
            j = r.get("judgement")
            if not isinstance(j, dict) or r.get("verdict") is None:
                continue
            rule = str(j.get("decision_rule", "simple"))
            out.append({"axis": axis, "set_rate_dps": r.get("set_rate_dps"),
                        "quantity": "rate_error", "value_rel": r.get("rate_error_rel"),
                        "u_rel": r.get("rate_error_u_rel"),
                        "tolerance_rel": j.get("tolerance_rel"), "verdict": r.get("verdict"),
                        "rule": "simple" if rule.startswith("simple") else rule,
                        "capability_ratio": j.get("capability_ratio"),
                        "capability_ok": j.get("capable")})
    return out


def _stand(src: Sources) -> dict[str, Any]:
    stand = dict(src.stand_file.get("stand", {}) or {})
    stand.update({k: v for k, v in (src.get("stand", {}) or {}).items() if v is not None})
    return stand


def _all_rates(src: Sources) -> list[dict[str, Any]]:
    return [r for ax in (src.get("axes", {}) or {}).values() for r in ax.get("rates", [])]


def _item(src: Sources, kind: str) -> tuple[str, str]:
    """(what was calibrated, its serial): for the drift procedure the platform under test
    and its gyros, for the rate ladder the rate table named in the stand file."""
    if kind == "drift-pulse":
        plat = src.stand_file.get("platform", {}) or {}
        ident = plat.get("identity", {}) or {}
        if ident:
            gyros = plat.get("gyros", {}) or {}
            names = "; ".join(
                f"{g}: " + ", ".join(
                    str(v) for v in (spec.get("model"), spec.get("serial") and
                                     f"serial {spec['serial']}") if v)
                if isinstance(spec, Mapping) and (spec.get("model") or spec.get("serial"))
                else f"{g}: serial not given in the stand file"
                for g, spec in gyros.items())
            text = f"{_text(ident.get('maker'))} {_text(ident.get('model'))}"
            if names:
                text += f", with its gyros ({names})"
            return text, _text(ident.get("serial"))
        return ("gyro platform (identity not given in the stand file's platform.identity)",
                NOT_RECORDED)
    stand = _stand(src)
    return f"{_text(stand.get('maker'))} {_text(stand.get('model'))}", _text(stand.get("serial"))


def _identification(src: Sources, issue: Issue, kind: str,
                    checks: list[dict[str, Any]]) -> tuple[Any, ...]:
    stand = _stand(src)
    cert = _cert(src)
    dates = src.get("dates", {}) or {}
    started = dates.get("started_utc") or _first_event(src, "session_start")
    completed = dates.get("completed_utc") or _last_event(src, "completed")
    item, serial = _item(src, kind)
    rows: list[tuple[str, str]] = [
        ("Certificate number", issue.number),
        ("Revision", f"{issue.revision}" + (f"; replaces certificate {issue.replaces}, "
                                            "which is withdrawn" if issue.replaces else
                                            " (first issue)")),
        ("Title of the work", _text(src.get("title") or src.procedure_file.get("title"))),
        ("Issued by", _text(cert.get("laboratory"))),
        ("Laboratory address", _text(cert.get("address"))),
    ]
    if cert.get("accreditation"):
        rows.append(("Accreditation", _text(cert["accreditation"])))
    rows += [
        ("Customer", _text(cert.get("customer"))),
        ("Customer address", _text(cert.get("customer_address"))),
        ("Customer contact", _text(cert.get("customer_contact"))),
        ("Item calibrated", item),
        ("Serial number", serial),
    ]
    if kind == "rate-ladder":
        rows.append(("Item: what was calibrated",
                     ", ".join(f"axis {a}" for a in (src.get("axes", {}) or {}))
                     + "; rates are signed in each axis's positive sense (the drive's "
                       "positive count direction), angles from the zero mark"))
    if kind == "drift-pulse":
        rows.append(("Test stand used", f"{_text(stand.get('maker'))} "
                                        f"{_text(stand.get('model'))}, serial "
                                        f"{_text(stand.get('serial'))}"))
    site = cert.get("site") or stand.get("location")
    rows.append(("Site of calibration", _text(site)))
    if stand.get("simulated"):
        rows.append(("Nature of the work", "SIMULATED run (instrument twins on real channels): "
                     "these results describe no physical item; every page is marked"))
    rows += [
        ("Procedure", {"rate-ladder": "rate ladder (docs/method.md part A)",
                       "drift-pulse": "drift by alternating-sign pulses (docs/method.md part B)"}
         .get(kind, kind)),
        ("Work started", _utc(started)),
        ("Work ended", (_utc(completed) + (" (aborted)" if src.get("aborted") else ""))
         if completed else "not completed"),
        ("Date of issue (authorisation)", issue.issue_date),
        ("Statement of conformity", _overall(src, checks, kind)),
    ]
    skip = {"laboratory", "customer", "number", "id", "certificate_id", "prefix", "signers",
            "signatories", "address", "accreditation", "customer_address", "customer_contact",
            "site", "lab", "authoritative", "specification"}
    rows += [(_label(k), _text(v)) for k, v in cert.items() if k not in skip]
    blocks: list[Any] = [Fields(tuple(rows))]
    run_dir = src.get("run_dir") or (src.run_path.name if src.run_path else NOT_RECORDED)
    blocks.append(software_note(src.meta, src.events, bench.__version__, str(run_dir)))
    blocks.append(Para(AUTHORITATIVE, "note"))
    return tuple(blocks)


def _first_event(src: Sources, kind: str) -> str | None:
    return next((e.get("utc") for e in src.events if e.get("event") == kind), None)


def _last_event(src: Sources, kind: str) -> str | None:
    found = [e.get("utc") for e in src.events if e.get("event") == kind]
    return found[-1] if found else None


def check_class(c: Mapping[str, Any]) -> str:
    """'consistency' (physics cross-check, not conformity), 'not-assessed' (excluded from
    conformity, e.g. a σ at the timing floor), or 'conformity'."""
    if str(c.get("rule")) == "consistency":
        return "consistency"
    if str(c.get("verdict")) == "not-assessed":
        return "not-assessed"
    return "conformity"


#: what each procedure measures that a datasheet may specify, beside the checked quantities
MEASURED = {
    "rate-ladder": (("rate_error", "per-turn rate error"),
                    ("rate_instability", "per-turn rate instability"),
                    ("systematic", "once-per-revolution and higher harmonics of the rate"),
                    ("mains", "mains-frequency ripple"),
                    ("intra_turn_instability", "intra-turn instability"),
                    ("stability_over_angle", "rate stability over 1°, 10°, 360°")),
    "drift-pulse": (("own_drift", "own drift"), ("apparent_drift", "apparent drift"),
                    ("azimuth", "platform azimuth")),
}


def _coverage(checks: list[dict[str, Any]], kind: str) -> tuple[list[str], list[str], int]:
    """(quantities the verdict covers, quantities not assessed, checks excluded)."""
    conf = [c for c in checks if check_class(c) == "conformity"]
    covered = list(dict.fromkeys(str(c.get("quantity")) for c in conf))
    names = [QUANTITY_NAMES.get(q, _label(q)) for q in covered]
    not_assessed = [text for key, text in MEASURED.get(kind, ()) if key not in covered]
    excluded = sum(1 for c in checks if check_class(c) == "not-assessed")
    return names, not_assessed, excluded


def _scope_line(src: Sources, checks: list[dict[str, Any]], kind: str) -> str:
    names, not_assessed, excluded = _coverage(checks, kind)
    if not names:
        return "No statement of conformity: the procedure states no tolerances."
    text = "The verdict covers: " + ", ".join(names) + "."
    if excluded:
        text += f" {excluded} check(s) could not be assessed (section Conformity)."
    if not_assessed:
        text += " Not assessed: " + ", ".join(not_assessed) + "."
    return text


def _overall(src: Sources, checks: list[dict[str, Any]], kind: str = "rate-ladder") -> str:
    verdict = str(src.get("verdict", "incomplete")).lower()
    conf = [c for c in checks if check_class(c) == "conformity"]
    failed = [c for c in conf if str(c.get("verdict", "")).lower() != "pass"]
    cons = [c for c in checks if check_class(c) == "consistency"]
    rule = _rule_name(src.get("decision_rule"))
    scope = _scope_line(src, checks, kind)
    cons_text = ""
    if cons:
        bad = sum(1 for c in cons if str(c.get("verdict")).lower() != "pass")
        cons_text = (f" Consistency checks (not conformity): {len(cons) - bad} of {len(cons)} "
                     "consistent" + (", the measurement is in doubt" if bad else "") + ".")
    if verdict == "incomplete":
        return ("INCOMPLETE: the run did not complete every step; no statement of conformity is "
                "made for the points not measured." + cons_text)
    excluded = sum(1 for c in checks if check_class(c) == "not-assessed")
    if not conf and excluded:
        return (f"NO STATEMENT OF CONFORMITY: none of the {excluded} check(s) could be "
                "assessed (section Conformity)." + cons_text)
    if not conf:
        return (f"{verdict.upper()}: no conformity check was made (the procedure states no "
                "tolerances)." + cons_text)
    if not failed:
        head = (f"PASS: all {len(conf)} conformity checks met the specification under the "
                f"{rule} decision rule (section Conformity).")
    else:
        head = (f"FAIL: {len(failed)} of {len(conf)} conformity checks did not meet the "
                f"specification under the {rule} decision rule (section Conformity).")
    return f"{head} {scope}{cons_text}"


def _rule_name(rule: Any) -> str:
    return {"guard-band": "guard-band (guarded acceptance, w = U)",
            "simple": "simple acceptance"}.get(str(rule or "simple"), str(rule))


def _instruments(src: Sources, kind: str) -> tuple[Any, ...]:
    stand = _stand(src)
    item, serial = _item(src, kind)
    what = "Test stand used (the laboratory's)" if kind == "drift-pulse" else "Rate table"
    blocks: list[Any] = [Fields((
        ("Item calibrated", f"{item}, serial {serial}"),
        (what, f"{_text(stand.get('maker'))} {_text(stand.get('model'))}, serial "
               f"{_text(stand.get('serial'))}"),
        ("Stand file", f"{_text(stand.get('file') or src.meta.get('stand_file'))}"),
        ("Stand file SHA-256", _text(stand.get("sha256") or src.meta.get("stand_sha256"))),
    ))]
    ids = src.get("instruments", {}) or {}
    if not ids:  # the event log records each axis's identities at the start of a session
        for e in src.events:
            if e.get("event") == "identity" and e.get("axis"):
                ids.setdefault(e["axis"], {}).update(
                    {k: v for k, v in e.items()
                     if k not in ("utc", "t_s", "session", "event", "axis")})
    stand_axes = src.stand_file.get("axes", {}) or {}
    rows = []
    for axis in dict.fromkeys([*ids, *stand_axes]):
        roles = dict.fromkeys([*(ids.get(axis) or {}), *(stand_axes.get(axis) or {})])
        for role in roles:
            if role == "counter_reference":
                continue   # in the traceability table
            ident = (ids.get(axis) or {}).get(role)
            conf = (stand_axes.get(axis) or {}).get(role) or {}
            conf = {k: v for k, v in conf.items() if k != "calibration"} \
                if isinstance(conf, Mapping) else conf
            setting = _text(conf) if conf else ""
            text = _text(ident) if ident else "identity not recorded"
            if role == "fog" and ident:
                text = ("as configured in the stand file (a FOG answers no identity query): "
                        + text)
            rows.append((axis, role, text, setting or "—"))
    if rows and all(r[3] == "—" for r in rows):
        blocks.append(Table(("Axis", "Instrument", "Identity (as reported)"),
                            tuple(r[:3] for r in rows), widths=(0.9, 1.0, 5.0), align="lll",
                            caption="Instruments used, with the identity each reported "
                                    "(*IDN?, drive identity objects, FOG model)"))
    elif rows:
        blocks.append(Table(("Axis", "Instrument", "Identity (as reported)", "Settings"),
                            tuple(rows), widths=(0.9, 1.0, 3.2, 3.6), align="llll",
                            caption="Instruments used, with the identity each reported "
                                    "(*IDN?, drive identity objects, FOG model)"))
    else:
        blocks.append(Para("Instrument identities: not recorded.", "note"))
    blocks += _shared_identities(rows)
    blocks += _traceability(src)
    return tuple(blocks)


def _shared_identities(rows: list[tuple[str, str, str, str]]) -> list[Any]:
    """Two instruments of one kind answering with one identity (maker, model, serial) are
    either one instrument or misreporting: the reader must be told."""
    seen: dict[tuple[str, str], list[str]] = {}
    for axis, role, ident, _ in rows:
        if role in ("counter", "drive") and ident and not ident.startswith("identity not"):
            seen.setdefault((role, ident), []).append(axis)
    return [Para(f"CHECK: the {role}s of axes {', '.join(axes)} report the same identity "
                 f"({ident}); two instruments cannot share a serial number. On a simulated "
                 "bench the twins answer their model's default identity.", "strong")
            for (role, ident), axes in seen.items() if len(axes) > 1]


def _work_date(src: Sources) -> dt.date | None:
    stamp = ((src.get("dates", {}) or {}).get("started_utc")
             or _first_event(src, "session_start") or src.meta.get("created_utc"))
    try:
        return dt.datetime.fromisoformat(str(stamp).replace("Z", "+00:00")).date()
    except (TypeError, ValueError):
        return None


def _traceability(src: Sources) -> tuple[Any, ...]:
    """Where each measured quantity's traceability to the SI comes from (17025 7.8.4.1 c):
    the stand file's calibration certificates, and the counter reference as read back."""
    items = traced_items(src.stand_file)
    if not items:
        return (Para("Metrological traceability: the stand file states no calibration "
                     "certificates; NOT SHOWN for any instrument.", "strong"),)
    on = _work_date(src)
    rows = []
    overdue_seen = False
    for t in items:
        if not t.stated:
            status = ("NOT TRACEABLE: no calibration certificate in the stand file"
                      if t.where.rsplit(".", 1)[-1] in MEASURING_ROLES else
                      "none stated (no measured value rests on it)")
        elif on is not None and t.overdue(on):
            overdue_seen = True
            status = f"PAST DUE on the date of the work ({on.isoformat()})"
        else:
            status = "valid on the work's date" if on else "validity not checked"
        rows.append((t.item, _text(t.certificate) if t.stated else "—",
                     _text(t.issuer) if t.stated else "—",
                     t.due.isoformat() if t.due else "—", _text(t.traces) if t.traces else
                     "—", status))
    notes = ["From the stand file (its SHA-256 above). Due dates are compared with the date "
             "the work started."]
    if overdue_seen:
        notes.append("An instrument past its calibration due date was used: the run warned "
                     "at its start; results depending on it are not shown to be traceable.")
    ids = src.get("instruments", {}) or {}
    refs = [(a, v.get("counter_reference")) for a, v in ids.items()
            if isinstance(v, Mapping) and v.get("counter_reference")]
    stand_axes = src.stand_file.get("axes", {}) or {}
    for axis, ref in refs:
        claimed = ((stand_axes.get(axis) or {}).get("counter") or {}).get("reference")
        notes.append(f"Counter reference, axis {axis}: read back from the counter: {ref}"
                     + (f"; the stand file states {claimed}" if claimed else "") + ".")
    return (Table(("Item", "Certificate", "Issued by", "Due", "Quantity traced",
                   "Status"), tuple(rows), widths=(1.9, 2.0, 1.6, 1.2, 2.2, 1.5),
                  align="llllll", caption="Metrological traceability: calibration of the "
                  "instruments and references used", notes=tuple(notes)),)


def _method(src: Sources, kind: str) -> tuple[Any, ...]:
    pf = src.get("procedure_file", {}) or {}
    name = pf.get("name") or src.meta.get("procedure_name")
    sha = pf.get("sha256") or src.meta.get("procedure_sha256")
    blocks: list[Any] = list(methods.B_TEXT if kind == "drift-pulse" else methods.A_TEXT)
    method = src.get("method", {}) or {}
    rows = [("Procedure file", _text(name)), ("Procedure file SHA-256", _text(sha))]
    rows += [(_label(k), _text(v)) for k, v in method.items()
             if k not in ("decision_rule", "tolerance", "turns_per_axis")]
    rows.append(("Decision rule", _rule_name(src.get("decision_rule"))))
    blocks.append(Fields(tuple(rows)))
    return tuple(blocks)


def _deviations(src: Sources, kind: str) -> tuple[Any, ...]:
    blocks: list[Any] = []
    if kind != "drift-pulse":
        seq = (src.get("method", {}) or {}).get("sequence")
        items = list(methods.A_IMPROVEMENTS)
        if seq in methods.SEQUENCE_TEXT:
            items.insert(0, methods.SEQUENCE_TEXT[seq])
        blocks.append(Para("From the source paper's method (each one an improvement, "
                           "docs/method.md A3-A5):", "strong"))
        blocks += [Para(f"• {t}") for t in items]
    run: list[str] = []
    sessions = src.get("sessions")
    if isinstance(sessions, int) and sessions > 1:
        run.append(f"The run was interrupted and resumed: it ran in {sessions} sessions. Each "
                   "unit (a ± pair) was measured whole within one session.")
    elif isinstance(sessions, list) and len(sessions) > 1:
        run.append(f"The run was interrupted and resumed: it ran in {len(sessions)} sessions.")
    if src.get("aborted"):
        run.append("The run was aborted before every step was done; the points not measured "
                   "are absent from the results.")
    if str(src.get("verdict")) == "incomplete":
        run.append("The result is incomplete: no statement of conformity is made for the "
                   "missing points.")
    for d in src.get("deviations", []) or []:
        run.append(_text(d))
    for where in src.dropped:
        run.append(f"result.json: {where} was malformed and is not reported here.")
    for axis, d in ((src.get("drift", {}) or {}).get("axes", {}) or {}).items():
        off = d.get("start_offset") if isinstance(d, Mapping) else None
        if isinstance(off, Mapping) and off.get("detected"):
            shift = format_value_u(_num(off.get("offset_s")), _num(off.get("offset_u_s")),
                                   1e3, signed=True).joined("ms")
            run.append(f"Axis {axis}: the digitizer's samples were {shift} "
                       "off the pulse edges; the integration edges were placed where the "
                       "pulses are (docs/method.md B: a half-sample offset would bias the drift).")
    blocks.append(Para("From the procedure, in this run:", "strong"))
    blocks += [Para(f"• {t}") for t in run] or [Para("None.")]
    return tuple(blocks)


def _conditions(src: Sources) -> tuple[Any, ...]:
    cond = src.get("conditions") or src.procedure_file.get("conditions") or {}
    if not cond:
        return (Para("No conditions were recorded in the procedure file."),
                *prompt_blocks(src.events))
    return (Para("As stated in the procedure file: the nominal conditions of the laboratory, "
                 "not measured during this run.", "note"),
            Fields(tuple((_label(k), _text(v)) for k, v in cond.items())),
            *prompt_blocks(src.events))


# -- rate ladder results -------------------------------------------------------------------

def _figure(caption: str, draw: Callable[..., bytes | None], *args: Any,
            width_frac: float = 1.0) -> list[Any]:
    """A plot as a figure block; data that cannot be drawn give a note, not a crash."""
    try:
        png = draw(*args)
    except (ValueError, TypeError, KeyError, IndexError, ZeroDivisionError) as e:
        return [Para(f"Figure not drawn ({caption}): its data are malformed ({e}).", "note")]
    return [Figure(png, caption, width_frac)] if png else []


def _tolerances(checks: Iterable[Mapping[str, Any]], axis: str
                ) -> dict[str, list[tuple[float, float]]]:
    out: dict[str, list[tuple[float, float]]] = {}
    for c in checks:
        rate, tol = _num(c.get("set_rate_dps")), _num(c.get("tolerance_rel"))
        if c.get("axis") == axis and rate is not None and tol is not None:
            out.setdefault(str(c.get("quantity")), []).append((abs(rate), tol))
    return {k: sorted(set(v)) for k, v in out.items()}


def _vu(value: Any, u: Any, unit: RelUnit | None = None, signed: bool = False) -> str:
    scale = unit.scale if unit else 1.0
    return format_value_u(_num(value), _num(u), scale, signed).joined()


def _instability_u(r: Mapping[str, Any]) -> tuple[float | None, bool]:
    """U of eq. 2's sigma: the result's, else the chi-square approximation (k = 2)."""
    u = _num(r.get("rate_instability_u_rel"))
    if u is not None:
        return u, False
    s, n = _num(r.get("rate_instability_rel")), len(r.get("counter_rate_dps") or [])
    u = std_u_rel(s, n or int(r.get("turns") or 0))
    return u, u is not None


def sigma_presented(r: Mapping[str, Any], u: float | None) -> Presented:
    """Eq. 2's σ under the one rule, with the timing floor as its zero: resolved when
    σ − U > floor (the analysis's `rate_instability_resolved`), else '< L', L the
    one-sided chi-square upper limit (`rate_instability_upper_rel`) or σ + U."""
    s = _num(r.get("rate_instability_rel"))
    floor = _num(r.get("rate_instability_floor_rel"))
    resolved = r.get("rate_instability_resolved")
    if resolved is None:
        resolved = (s is not None and u is not None
                    and s - u > (floor if floor is not None else 0.0))
    upper = _num(r.get("rate_instability_upper_rel"))
    return present(s, u, resolved=bool(resolved), upper=upper)


def _u_of_std(s: float | None, n: Any) -> float | None:
    """U (k = 2) of a standard deviation from n values, when the result does not give it."""
    n = _num(n)
    return None if n is None else std_u_rel(s, int(n))


@dataclass(frozen=True)
class Averaged:
    """The random part averaged over windows of `angle_deg` of table angle (docs/method.md A5)."""

    angle_deg: float
    raw: float | None
    u: float | None
    u_approx: bool
    floor: float | None
    corrected: float | None
    blocks: int | None
    upper: float | None = None        # k = 2 upper limit of the corrected figure
    resolved: bool | None = None

    @property
    def sensitivity(self) -> float | None:
        """The smallest table figure these n windows could resolve: where the excess
        variance equals 2 u of the measured variance, (8 / (n - 1))^(1/4) * measured."""
        if self.raw is None or not self.blocks or self.blocks < 2:
            return None
        return self.raw * (8.0 / (self.blocks - 1)) ** 0.25


def _averaged(r: Mapping[str, Any]) -> list[Averaged]:
    """Averages over 1/10/360 deg, from `intra_turn.averaged` (the analysis library's shape)
    or a list/mapping under one of the older names."""
    data: Any = (r.get("intra_turn") or {}).get("averaged")
    for key in ("instability_over_angle", "intra_turn_instability_over", "averaged_instability"):
        data = data if data is not None else r.get(key)
    if isinstance(data, Mapping):
        data = [{"angle_deg": a, **(v if isinstance(v, Mapping) else {"instability_rel": v})}
                for a, v in data.items()]
    out = []
    for d in data or []:
        if not isinstance(d, Mapping) or _num(d.get("angle_deg")) is None:
            continue
        raw = _num(d.get("instability_rel", d.get("rel")))
        u = _num(d.get("u_rel"))
        approx = u is None
        if approx:
            u = _u_of_std(raw, d.get("blocks"))
        corrected, upper = _num(d.get("corrected_rel")), _num(d.get("corrected_upper_rel"))
        resolved = d.get("resolved")
        if resolved is None:   # an older result: the k = 2 test on the excess variance
            resolved = bool(corrected) and u is not None and raw is not None \
                and corrected ** 2 > 2 * raw * u
        if upper is None and raw is not None and u is not None:
            fl = _num(d.get("floor_rel")) or 0.0
            upper = math.sqrt(max(raw * raw - fl * fl, 0.0) + 2 * raw * u)
        out.append(Averaged(float(d["angle_deg"]), raw, u, approx and u is not None,
                            _num(d.get("floor_rel")), corrected,
                            int(d["blocks"]) if _num(d.get("blocks")) is not None else None,
                            upper, bool(resolved)))
    return sorted(out, key=lambda x: x.angle_deg)


def _ladder_results(src: Sources, number: str, checks: list[dict[str, Any]]
                    ) -> list[Section]:
    axes = src.get("axes", {}) or {}
    out = [Section(number, "Results", (Para(
        "Per axis, commanded rate and direction. Each value is followed by its expanded "
        "uncertainty U (k = 2, about 95 %). Signed rates: + is the table's positive sense."),
        Para("Quantities that may not be resolved. " + RESOLUTION_RULE, "note")),
        )]
    sub = 0
    # one unit per quantity on the whole certificate, whatever the axis
    every = [r for ax in axes.values() for r in ax.get("rates", []) if isinstance(r, dict)]
    for axis, ax in axes.items():
        rates = [r for r in ax.get("rates", []) if isinstance(r, dict)]
        pairs = [p for p in ax.get("pairs", []) if isinstance(p, dict)]
        sub += 1
        out.append(Section(f"{number}.{sub}", f"Axis {axis}",
                           _axis_blocks(axis, rates, pairs, ax, checks, every), level=2))
    figs = _across_axes(axes)
    if figs:
        sub += 1
        out.append(Section(f"{number}.{sub}", "All axes: trends with rate", tuple(figs), level=2))
    if not axes:
        out.append(Section(f"{number}.1", "No results", (Para(
            "The result carries no axis results: nothing was measured to completion."),),
            level=2))
    return out


def _axis_blocks(axis: str, rates: list[dict[str, Any]], pairs: list[dict[str, Any]],
                 ax: Mapping[str, Any], checks: list[dict[str, Any]],
                 every: list[dict[str, Any]]) -> tuple[Any, ...]:
    """One axis's results; `every` is every axis's rates, so that one quantity has one
    unit on the whole certificate."""
    blocks: list[Any] = []
    # A1/A2 per-turn
    err_unit = rel_unit(*[v for r in every for v in (_num(r.get("rate_error_rel")),
                                                      _num(r.get("rate_error_u_rel")))],
                        *[t for c in checks if c.get("quantity") == "rate_error"
                          for t in (_num(c.get("tolerance_rel")),)])
    inst_us = [_instability_u(r) for r in rates]
    inst_unit = rel_unit(*[_num(r.get("rate_instability_rel")) for r in every],
                         *[_instability_u(r)[0] for r in every])
    rows = []
    approximated = False
    unresolved_sigma = False
    for r, (iu, approx) in zip(rates, inst_us, strict=True):
        approximated |= approx
        set_rate = _num(r.get("set_rate_dps"))
        mean = _num(r.get("mean_rate_dps"))
        cr = [v for v in (_num(x) for x in r.get("counter_rate_dps") or []) if v is not None]
        if mean is None and cr:
            mean = sum(cr) / len(cr)
        eu = _num(r.get("rate_error_u_rel"))
        mean_u = eu * abs(set_rate) if eu is not None and set_rate else None
        sigma = sigma_presented(r, iu)
        unresolved_sigma |= not sigma.resolved
        rows.append((_rate(set_rate), _text(r.get("turns")),
                     format_value_u(mean, mean_u, signed=True, sig_without_u=10).joined(),
                     _vu(r.get("rate_error_rel"), eu, err_unit, signed=True),
                     present(_num(r.get("rate_instability_rel")), iu, inst_unit.scale,
                             resolved=sigma.resolved, upper=sigma.limit).text
                     + ("*" if approx and sigma.resolved else ""),
                     format_sig(_num(r.get("rate_instability_floor_rel")) * inst_unit.scale, 2)
                     if _num(r.get("rate_instability_floor_rel")) is not None else "—",
                     verdict_label(r.get("verdict"))))
    notes = ["Timing floor of σ = ΔT / T, with ΔT = √2 · Δ_edge the timing of one period "
             "(section 3, A1): the σ the counter's and the zero-mark sensor's timing errors "
             "alone would give."]
    if unresolved_sigma:
        notes.append("'< L': σ is not resolved above the timing floor (σ − U ≤ floor): L is "
                     "its one-sided 97.5 % upper limit for normal per-turn rates (chi-square, "
                     "N − 1 degrees of freedom); such a σ is left out of conformity.")
    if approximated:
        notes.append("* U of σ from the chi-square approximation U = 2σ/√(2(N−1)) for N turns "
                     "(normal per-turn rates); the result did not carry it.")
    blocks.append(Table(
        ("Set rate, °/s", "Turns", "Mean rate ± U, °/s",
         f"Rate error δ ± U, {err_unit.name}", f"Instability σ ± U, {inst_unit.name}",
         f"Timing floor of σ, {inst_unit.name}", "Verdict"),
        tuple(rows), widths=(0.9, 0.6, 2.8, 1.8, 1.8, 1.1, 0.9), align="rcrrrrc",
        caption=f"Axis {axis}: per-turn rate error and instability (docs/method.md A1-A2, eqs. 1-2)",
        notes=tuple(notes)))
    budget = _rate_error_budget(axis, rates)
    if budget is not None:
        blocks.append(budget)
    blocks += _figure(f"Axis {axis}: per-turn rate error and instability vs rate, both "
                      "directions (cf. paper figs. 4-5)",
                      plots.per_turn, axis, rates, _tolerances(checks, axis),
                      (f"δ, {err_unit.name}", err_unit.scale),
                         (f"σ, {inst_unit.name}", inst_unit.scale))
    # A3 cross-calibration
    if pairs:
        prow = []
        has_drift = any(_num(p.get("drift_dps_per_h")) is not None for p in pairs)
        for p in pairs:
            w0, w0u = _num(p.get("w0_dps")), _num(p.get("w0_u_dps"))
            row = [f"±{_num(p.get('rate_dps')) or 0:g}", _vu(p.get("k"), p.get("k_u")),
                   _vu(w0, w0u, signed=True),
                   format_value_u(w0, w0u, 3600.0, signed=True).joined()]
            if has_drift:
                row.append(_vu(p.get("drift_dps_per_h"), p.get("drift_u_dps_per_h"),
                               signed=True))
            prow.append(tuple(row))
        header = ["Pair, °/s", "k ± U", "ω0 ± U, °/s", "ω0 ± U, °/h"]
        notes = []
        if has_drift:
            header.append("Bias drift ± U, °/s per h")
            methods_used = sorted({CALIBRATION_METHODS.get(str(p.get("method")),
                                                           str(p.get("method")))
                                   for p in pairs if p.get("method")})
            sources = sorted({str(p.get("drift_source")) for p in pairs
                              if p.get("drift_source")})
            notes.append("ω0 is the bias at the pair's reference time; the FOG's bias drift "
                         "during the pair is estimated and removed"
                         + (f" ({'; '.join(methods_used)}" if methods_used else "")
                         + (f"; drift from {', '.join(sources)})" if sources else
                            (")" if methods_used else "")) + ".")
        for p in pairs:  # a resumed pair: which half came from which session (docs/resume.md)
            hs = [int(s) for s in p.get("half_sessions") or [] if isinstance(s, int | float)]
            if len(set(hs)) > 1:
                notes.append(f"Pair ±{_num(p.get('rate_dps')) or 0:g} °/s was resumed: "
                             + ", ".join(f"half {i + 1} from session {s}"
                                         for i, s in enumerate(hs))
                             + f". FOG bias {p.get('bias_model', '')}.")
        blocks.append(Table(tuple(header), tuple(prow),
                            widths=(1.0, 2.4, 2.1, 1.9, 2.1)[:len(header)], align="rrrrr"[
                                :len(header)],
                            caption=f"Axis {axis}: FOG cross-calibration per ± pair "
                                    "(docs/method.md A3, eqs. 5-6)", notes=tuple(notes)))
    # A4 systematic
    sys_rows, mains_rows = [], []
    amp_unit = rel_unit(*[_num(h.get("amplitude_rel")) for r in every
                          for h in (r.get("systematic") or {}).get("harmonics") or []])
    for r in rates:
        s = r.get("systematic") or {}
        for h in s.get("harmonics") or []:
            a, au = _num(h.get("amplitude_rel")), _num(h.get("amplitude_u_rel"))
            w = abs(_num(r.get("set_rate_dps")) or 0.0)
            detected = h.get("detected")
            resolved = bool(detected) if detected is not None else is_resolved(a, au)
            sys_rows.append((_rate(r.get("set_rate_dps")), _text(h.get("order")),
                             present(a, au, amp_unit.scale, resolved=resolved).text,
                             present(a * w if a is not None else None,
                                     au * w if au is not None else None,
                                     resolved=resolved).text,
                             present_phase(_num(h.get("phase_deg")), _num(h.get("phase_u_deg")),
                                           resolved)))
        m = s.get("mains") or {}
        if m:
            w = abs(_num(r.get("set_rate_dps")) or 0.0)
            a, au = _num(m.get("amplitude_dps")), _num(m.get("amplitude_u_dps"))
            detected = m.get("detected")
            resolved = bool(detected) if detected is not None else is_resolved(a, au)
            mains_rows.append((_rate(r.get("set_rate_dps")), _text(m.get("frequency_hz")),
                               present(a, au, resolved=resolved).text,
                               present(a / w if a is not None and w else None,
                                       au / w if au is not None and w else None,
                                       PERCENT.scale, resolved=resolved).text,
                               present_phase(_num(m.get("phase_deg")),
                                             _num(m.get("phase_u_deg")), resolved)))
    if sys_rows:
        blocks.append(Table(("Set rate, °/s", "Order h", f"Amplitude ± U, {amp_unit.name} "
                             "of ω_set", "Amplitude ± U, °/s", "Phase p_h ± U, °"),
                            tuple(sys_rows), widths=(1.1, 0.8, 2.4, 2.2, 1.8), align="rcrrr",
                            caption=f"Axis {axis}: systematic intra-turn component, fitted "
                                    "harmonics Δω_sys = ω_set·Σ a_h cos(hφ + p_h) "
                                    "(docs/method.md A4)",
                            notes=("'< L': the amplitude is not resolved (a ≤ U, the one "
                                   "rule of section 6); L = a + U is its one-sided upper "
                                   "limit, and its phase, which then means nothing, is "
                                   "printed '—'.",)))
    if mains_rows:
        blocks.append(Table(("Set rate, °/s", "Frequency, Hz", "Amplitude ± U, °/s",
                             "Amplitude ± U, % of ω_set", "Phase ± U, °"), tuple(mains_rows),
                            widths=(1.1, 1.0, 2.2, 2.2, 1.6), align="rrrrr",
                            caption=f"Axis {axis}: mains-frequency ripple, fitted in time "
                                    "(docs/method.md A4)",
                            notes=("One tone of fixed frequency and phase over each "
                                   "direction's record. Grid-frequency wander during the "
                                   "record (of the order of 1 / record length or more) "
                                   "spreads the tone and lowers the amplitude found; "
                                   "'< L' and '—' as for the harmonics.",)))
    blocks += _figure(f"Axis {axis}: systematic component vs table angle with the fitted "
                      "harmonics (cf. paper figs. 8-9)",
                      plots.systematic, axis, rates, amp_unit.scale, amp_unit.name)
    # A5 intra-turn
    blocks += _intra_blocks(axis, rates, ax.get("noise_floor") or {}, every)
    return tuple(blocks)


def _corrected_cell(r: Mapping[str, Any], unit: RelUnit) -> str:
    """Floor-corrected instability under the one rule: value ± U when resolved and a U is
    given, else its k = 2 upper limit '< L' (never a bare value)."""
    intra = r.get("intra_turn") or {}
    value = _num(r.get("intra_turn_instability_corrected_rel"))
    u = _num(r.get("intra_turn_instability_corrected_u_rel"))
    upper = _num(intra.get("corrected_upper_rel"))
    resolved = intra.get("resolved")
    if u is not None and resolved is not False:
        return present(value, u, unit.scale, resolved=True).text
    if resolved and value is not None and upper is not None and upper > value:
        # the limit's distance from the value is its k = 2 half-width (one-sided)
        return present(value, upper - value, unit.scale, resolved=True).text
    if upper is None and value == 0.0:
        return "0 (noiseless FOG)"   # a simulated FOG without noise: nothing to remove
    return present(value, None, unit.scale, resolved=False, upper=upper).text


#: the analysis's names for its cross-calibration methods, in words (docs/method.md A3)
CALIBRATION_METHODS = {
    "lsq-drift": "k, ω0 and a linear bias drift fitted by least squares to the halves' means",
    "eq5-6": "k and ω0 from eqs. 5-6",
    "eq5-6, drift-corrected": "k and ω0 from eqs. 5-6 after removing the bias drift",
}

BUDGET_TERMS = (("timing_u_rel", "zero-mark timing"), ("timebase_u_rel", "counter timebase"),
                ("repeatability_u_rel", "repeatability (Type A)"))


def _rate_error_budget(axis: str, rates: list[dict[str, Any]]) -> Table | None:
    """The standard uncertainties behind U of the rate error (docs/method.md A1-A2)."""
    budgets = [(r, r.get("rate_error_budget")) for r in rates
               if isinstance(r.get("rate_error_budget"), Mapping)]
    if not budgets:
        return None
    terms = [(k, name) for k, name in BUDGET_TERMS if any(k in b for _, b in budgets)]
    unit = rel_unit(*[_num(b.get(k)) for _, b in budgets for k, _ in terms],
                    *[_num(r.get("rate_error_u_rel")) for r, _ in budgets])
    rows = []
    for r, b in budgets:
        cells = [format_sig((_num(b.get(k)) or math.nan) * unit.scale, 2) for k, _ in terms]
        u = _num(r.get("rate_error_u_rel"))
        rows.append((_rate(r.get("set_rate_dps")), *cells,
                     format_sig(u * unit.scale, 2) if u is not None else "n/a"))
    first = budgets[0][1]
    parts = []
    for key, text, scale, unit_name in (("timestamp_u_s", "counter single-shot timestamp", 1e9, "ns"),
                                        ("trigger_jitter_s", "zero-mark edge jitter", 1e9, "ns"),
                                        ("timebase_limit_rel", "timebase limit", 1e6, "ppm"),
                                        ("time_tie_u_s", "time tie to the FOG axis (moves "
                                         "the FOG window and the harmonics' phase, not the "
                                         "counter's rate)", 1e6, "µs")):
        v = _num(first.get(key))
        if v is not None:
            parts.append(f"{text} {format_sig(v * scale, 2)} {unit_name}")
    notes = ["Standard uncertainties (k = 1), relative to the set rate; U = k·√(Σu²), "
             f"k = {_num(first.get('coverage_factor')) or 2:g}."]
    if parts:
        notes.append("Inputs: " + "; ".join(parts) + " (docs/method.md A1: ΔT = √(Δ_counter² + "
                     "Δ_trigger²)).")
    header = ("Set rate, °/s", *[f"u({name}), {unit.name}" for _, name in terms],
              f"U (k = 2), {unit.name}")
    return Table(header, tuple(rows), widths=(1.1, *([1.8] * len(terms)), 1.4),
                 align="r" * len(header),
                 caption=f"Axis {axis}: uncertainty budget of the per-turn rate error",
                 notes=tuple(notes))


def _intra_blocks(axis: str, rates: list[dict[str, Any]], floor: Mapping[str, Any],
                  every: list[dict[str, Any]]) -> list[Any]:
    if not any(r.get("intra_turn_instability_rel") is not None for r in rates):
        return []
    raws = [_num(r.get("intra_turn_instability_rel")) for r in rates]
    raw_us: list[float | None] = []
    approx = False
    for r, raw in zip(rates, raws, strict=True):
        u = _num(r.get("intra_turn_instability_u_rel"))
        if u is None:
            u = _u_of_std(raw, (r.get("intra_turn") or {}).get("samples"))
            approx |= u is not None
        raw_us.append(u)
    floors = [_num((r.get("intra_turn") or {}).get("floor_rel")) for r in rates]
    raw_unit = rel_unit(*[_num(r.get("intra_turn_instability_rel")) for r in every])
    corr_unit = rel_unit(*[_num(r.get("intra_turn_instability_corrected_rel")) for r in every],
                         *[_num((r.get("intra_turn") or {}).get("corrected_upper_rel"))
                           for r in every])
    rows = []
    for r, raw, u, fl in zip(rates, raws, raw_us, floors, strict=True):
        rows.append((_rate(r.get("set_rate_dps")),
                     _vu(raw, u, raw_unit) + ("*" if u is not None and approx
                                                and r.get("intra_turn_instability_u_rel") is None
                                                else ""),
                     format_value_u(fl, None, raw_unit.scale, sig_without_u=2).value
                     if fl is not None else "—",
                     _corrected_cell(r, corr_unit)))
    header = ("Set rate, °/s", f"Raw ± U, {raw_unit.name}", f"FOG floor, {raw_unit.name}",
              f"Floor-corrected, {corr_unit.name}")
    notes = []
    bw = {_num(r.get("bandwidth_hz", (r.get("intra_turn") or {}).get("bandwidth_hz")))
          for r in rates} - {None}
    if bw:
        notes.append("At the FOG's output bandwidth: "
                     + ", ".join(f"{b:g} Hz" for b in sorted(bw)) + ".")
    sources = {str((r.get("intra_turn") or {}).get("floor_source")) for r in rates
               if (r.get("intra_turn") or {}).get("floor_source")}
    if floor or sources:
        noise = _num(floor.get("noise_dps", floor.get("sigma_dps",
                                                        floor.get("sample_std_dps"))))
        text = "FOG noise floor from " + (", ".join(sorted(sources)) if sources else
                                          str(floor.get("source", "a record at rest")))
        if noise is not None:
            text += f"; {format_sig(noise, 3)} °/s per sample"
        if _num(floor.get("rate_hz")) is not None:
            text += f" at {_num(floor.get('rate_hz')):g} Hz"
        if _num(floor.get("duration_s")) is not None:
            text += f", {_num(floor.get('duration_s')):g} s record at rest"
        notes.append(text + ". Floor-corrected = √(raw² − floor²) ± U when the table's own "
                            "part stands out of the FOG's noise (raw² − floor² > its U, the "
                            "one rule); otherwise '< L', L = √(max(raw² − floor², 0) + U) "
                            "its one-sided k = 2 upper limit.")
    if approx:
        notes.append("* U of the raw value from 2s/√(2(n−1)) over its n samples, assuming "
                     "independent samples; the result did not carry it.")
    blocks: list[Any] = [Table(header, tuple(rows), widths=(1.1, 2.0, 1.4, 2.2),
                               align="rrrr", caption=f"Axis {axis}: intra-turn instability "
                               "std(Δω_rand)/|ω_set| (docs/method.md A5)", notes=tuple(notes))]
    blocks += _stability_blocks(axis, rates)
    return blocks


def _stability_blocks(axis: str, rates: list[dict[str, Any]]) -> list[Any]:
    """Rate stability over an angle, as a datasheet states it (docs/method.md A5): over 1° and
    10° from the FOG (with what this FOG can verify), over 360° from the counter's
    per-turn rates, whose timing floor is far below the FOG's."""
    rows = []
    limited = False
    for r in rates:
        for a in _averaged(r):
            if a.angle_deg >= 360.0:
                continue   # one turn: the counter's σ below
            unit = PPM
            own = (present(a.corrected, a.upper - a.corrected, unit.scale, resolved=True).text
                   if a.resolved and a.corrected is not None and a.upper is not None
                   and a.upper > a.corrected else
                   present(a.corrected, None, unit.scale, resolved=False, upper=a.upper).text)
            limited |= not a.resolved
            rows.append((_rate(r.get("set_rate_dps")), f"{a.angle_deg:g}", "FOG",
                         present(a.raw, a.u, unit.scale, resolved=True).text
                         + ("*" if a.u_approx else ""),
                         format_sig(a.floor * unit.scale, 2) if a.floor is not None else "—",
                         own, format_sig(a.sensitivity * unit.scale, 2)
                         if a.sensitivity is not None else "—", _text(a.blocks)))
        s, (iu, approx) = _num(r.get("rate_instability_rel")), _instability_u(r)
        if s is not None:
            sigma = sigma_presented(r, iu)
            unit = PPM
            floor = _num(r.get("rate_instability_floor_rel"))
            rows.append((_rate(r.get("set_rate_dps")), "360", "counter",
                         present(s, iu, unit.scale, resolved=True).text
                         + ("*" if approx else ""),
                         format_sig(floor * unit.scale, 2) if floor is not None else "—",
                         present(s, iu, unit.scale, resolved=sigma.resolved,
                                 upper=sigma.limit).text,
                         format_sig(floor * unit.scale, 2) if floor is not None else "—",
                         _text(r.get("turns"))))
    if not rows:
        return []
    approx_note = ["* U from 2s/√(2(n−1)) over the n windows (turns); the result did not "
                   "carry it."] if any(r[3].endswith("*") for r in rows) else []
    notes = ["Rate stability over an angle: the standard deviation of the table rate averaged "
             "over consecutive windows of that angle, relative to |ω_set|, as a rate-table "
             "datasheet states it. Over 1° and 10° it comes from the FOG (floor: the FOG's own "
             "noise averaged over the window; table's own = √(measured² − floor²)); over 360° "
             "from the counter's per-turn rates (σ of eq. 2; floor: the timing floor).",
             "Capability: 'smallest verifiable' is the smallest table figure this measurement "
             "could show as resolved, (8/(n − 1))^¼ × measured for n windows, or the "
             "counter's timing floor. A datasheet figure below it cannot be verified with "
             "this FOG or counter; '< L' states only that the table is within L.",
             *approx_note]
    return [Table(("Set rate, °/s", "Window, °", "From", "Measured ± U, ppm", "Floor, ppm",
                   "Table's own, ppm", "Smallest verifiable, ppm", "Windows"), tuple(rows),
                  widths=(1.0, 0.8, 0.8, 1.8, 0.9, 1.6, 1.2, 0.8),
                  align="rrlrrrrr",
                  caption=f"Axis {axis}: rate stability over 1°, 10° and 360° (docs/method.md A5)",
                  notes=tuple(notes))]


def _across_axes(axes: Mapping[str, Any]) -> list[Any]:
    rates = {a: [r for r in ax.get("rates", []) if isinstance(r, dict)] for a, ax in axes.items()}
    blocks: list[Any] = []
    amp_unit = rel_unit(*[_num(h.get("amplitude_rel")) for rr in rates.values() for r in rr
                          for h in (r.get("systematic") or {}).get("harmonics") or []])
    blocks += _figure("Once-per-revolution amplitude vs rate, relative and absolute "
                      "(cf. paper fig. 7)",
                      plots.one_rev, rates, amp_unit.scale, amp_unit.name)
    unit = rel_unit(*[_num(r.get("intra_turn_instability_rel")) for rr in rates.values()
                      for r in rr])
    blocks += _figure("Intra-turn instability vs rate, raw and floor-corrected "
                      "(cf. paper fig. 10)",
                      plots.intra_turn, rates, unit.scale, unit.name)
    blocks += _figure("FOG scale k and bias ω0 per ± pair (docs/method.md A3)",
                      plots.pairs, {a: [p for p in ax.get("pairs", []) if isinstance(p, dict)]
                                    for a, ax in axes.items()})
    blocks += _figure("Allan deviation of the FOG at rest: its noise floor (docs/method.md A5)",
                      plots.allan, {a: ax.get("noise_floor") or {} for a, ax in axes.items()},
                      width_frac=0.8)
    return blocks


def _per_turn_annex(src: Sources) -> tuple[Any, ...]:
    rows = []
    for axis, ax in (src.get("axes", {}) or {}).items():
        for r in ax.get("rates", []):
            w_set = _num(r.get("set_rate_dps"))
            cr = [_num(x) for x in r.get("counter_rate_dps") or []]
            if not w_set or not cr:
                continue
            dev = ", ".join(format_sig(((x or math.nan) / w_set - 1) * 1e6, 3, signed=True)
                            .replace("n/a", "—") for x in cr)
            rows.append((axis, _rate(w_set), dev))
    return (Table(("Axis", "Set rate, °/s", "Per-turn rate deviations (ω_i/ω_set − 1), ppm, "
                   "in turn order"), tuple(rows), widths=(0.9, 1.1, 6.0), align="lrl",
                  caption="Per-turn counter rates (docs/method.md A1), relative to the set rate"),)


# -- drift-pulse results -------------------------------------------------------------------

def _position(c: Mapping[str, Any]) -> float:
    return _num(c.get("position_deg", c.get("table_deg"))) or 0.0


def _drift_results(src: Sources, number: str) -> list[Section]:
    drift = src.get("drift", {}) or {}
    axes = {a: d for a, d in (drift.get("axes", {}) or {}).items() if isinstance(d, Mapping)}
    blocks: list[Any] = [Para("Drift in °/h; each value followed by its expanded uncertainty "
                              "U (k = 2, about 95 %).")]
    has_nominal = any(_num(d.get("own_nominal_edges_dph")) is not None for d in axes.values())
    rows = []
    for axis, d in axes.items():
        row = [axis, _vu(d.get("own_dph"), d.get("own_u_dph"), signed=True),
               _vu(d.get("apparent_dph"), d.get("apparent_u_dph"), signed=True),
               _text(len(d.get("cycles") or []) or None)]
        if has_nominal:
            row.insert(3, format_sig(_num(d.get("own_nominal_edges_dph")) or math.nan, 4,
                                     signed=True))
        rows.append(tuple(row))
    if rows:
        header = ["Axis", "Own drift ± U, °/h", "Apparent drift at 0° ± U, °/h", "Cycles"]
        notes = []
        if has_nominal:
            header.insert(3, "Own drift at nominal edges, °/h")
            notes.append("Own drift at nominal edges: the same cycles integrated with the "
                         "pulse edges at the digitizer's nominal sample times, as the paper's "
                         "integrator does; shown for comparison only.")
        blocks.append(Table(tuple(header), tuple(rows),
                            widths=(0.8, 2.2, 2.6, 2.0, 0.8)[:len(header)] if has_nominal
                            else (0.8, 2.4, 2.8, 1.0), align="lrrrr"[:len(header)],
                            caption="Own and apparent drift per axis (docs/method.md B)",
                            notes=tuple(notes)))
    fields = []
    if _num(drift.get("latitude_deg")) is not None:
        fields.append(("Site latitude", f"{_num(drift['latitude_deg']):g}°"))
    if _num(drift.get("azimuth_deg")) is not None:
        az, azu = _num(drift["azimuth_deg"]), _num(drift.get("azimuth_u_deg"))
        fields.append(("Platform azimuth (X input axis) ± U", _vu(az, azu) + " °"))
        if azu is not None:
            fields.append(("U of the azimuth", format_value_u(azu * 60, None, sig_without_u=2)
                           .joined("arcmin")))
    if _num(drift.get("earth_horizontal_dph")) is not None:
        text = _vu(drift["earth_horizontal_dph"], drift.get("earth_horizontal_u_dph")) + " °/h"
        exp = _num(drift.get("earth_horizontal_expected_dph"))
        if exp is not None:
            ok = drift.get("earth_horizontal_consistent")
            text += (f"; expected 15.041·cos(latitude) = {exp:.4f} °/h"
                     + ("" if ok is None else (", consistent" if ok else ", NOT consistent")))
        fields.append(("Horizontal Earth rate from the apparent drifts", text))
    if fields:
        blocks.append(Fields(tuple(fields)))
    prow = []
    for axis, d in axes.items():
        positions = [p for p in d.get("positions") or [] if isinstance(p, Mapping)]
        if not positions:  # group the cycles by position
            cycles = [c for c in d.get("cycles") or [] if isinstance(c, Mapping)]
            for pos in dict.fromkeys(_position(c) for c in cycles):
                w = [v for c in cycles if _position(c) == pos
                     for v in (_num(c.get("drift_dph")),) if v is not None]
                if w:
                    mean = sum(w) / len(w)
                    std = (math.sqrt(sum((x - mean) ** 2 for x in w) / (len(w) - 1))
                           if len(w) > 1 else None)
                    positions.append({"table_deg": pos, "cycles": len(w), "mean_dph": mean,
                                      "std_dph": std, "drifts_dph": w})
        for p in positions:
            w = [v for v in (_num(x) for x in p.get("drifts_dph") or []) if v is not None]
            prow.append((axis, f"{_position(p):g}", _text(p.get("cycles", len(w))),
                         _vu(p.get("mean_dph"), p.get("u_dph"), signed=True),
                         format_sig(_num(p.get("std_dph")) or math.nan, 2),
                         ", ".join(format_sig(x, 5, signed=True) for x in w)))
    if prow:
        blocks.append(Table(("Axis", "Position, °", "Cycles", "Mean ± U, °/h", "Std, °/h",
                             "Drift per cycle, °/h, in order"), tuple(prow),
                            widths=(0.6, 0.8, 0.6, 1.8, 0.8, 4.0), align="lrrrrl",
                            caption="Drift per platform position and per cycle"))
    brow = []
    for axis, d in axes.items():
        budget = d.get("budget") or {}
        own, app = budget.get("own_u_dph") or {}, budget.get("apparent_u_dph") or {}
        for src_name in dict.fromkeys([*own, *app]):
            brow.append((axis, _label(src_name),
                         format_sig(_num(own.get(src_name)) or math.nan, 2),
                         format_sig(_num(app.get(src_name)) or math.nan, 2)))
    if brow:
        blocks.append(Table(("Axis", "Source", "u(own), °/h", "u(apparent), °/h"),
                            tuple(brow), widths=(0.7, 3.5, 1.5, 1.5), align="llrr",
                            caption="Uncertainty budget: standard uncertainties (k = 1) per "
                                    "source; U above is 2 × their root sum of squares"))
    blocks += _figure("Drift estimate per cycle, by axis and platform position",
                      plots.drift_cycles,
                      {a: {**d, "cycles": [{**c, "position_deg": _position(c)}
                                           for c in d.get("cycles") or []]}
                       for a, d in axes.items()})
    for axis, d in axes.items():
        cyc = d.get("example_cycle")
        if isinstance(cyc, Mapping):
            blocks += _figure(f"Axis {axis}: U(t) and the integrator output over one cycle",
                              plots.drift_cycle, axis, cyc)
    return [Section(number, "Results", tuple(blocks))]


# -- conformity, records, signatures -------------------------------------------------------

def decision_rule_text(rule: str) -> str:
    if rule == "guard-band":
        return ("Decision rule: guarded acceptance with a guard band equal to U (ILAC-G8:09/2019 "
                "§4.2.2). A check PASSES when |value| + U ≤ T and FAILS when |value| > T. When "
                "|value| ≤ T < |value| + U the measured value is inside the tolerance but within "
                "U of its limit, so conformity is not shown: this is stated as FAIL (guard "
                "band). For σ the guard is its one-sided 97.5 % upper limit (chi-square with "
                "N − 1 degrees of freedom) in place of |value| + U. Risk: the probability of a "
                "false accept is at most about 2.5 % where the value's distribution is normal "
                "(the rate error: a mean of N turns with the small-sample factor of section 3) "
                "or, for σ, where the per-turn rates are normal; it is not claimed for other "
                "distributions.")
    return ("Decision rule: simple acceptance (ILAC-G8:09/2019 §4.2.1, shared risk). A check "
            "PASSES when |value| ≤ T and FAILS when |value| > T; U is reported but not used in "
            "the decision. For a value close to the limit the probability of a false accept "
            "may approach 50 %; the capability column shows where U is small enough for this "
            "rule to be sound.")


ABSOLUTE_UNITS = {"dph": "°/h", "dps": "°/s", "deg": "°", "arcmin": "arcmin", "s": "s"}


@dataclass(frozen=True)
class CheckRow:
    """One check, whatever its unit: relative (`value_rel`) or absolute (`value_dph`...)."""

    value: float | None
    u: float | None
    tolerance: float | None
    expected: float | None
    suffix: str            # rel, dph, dps, deg...

    @classmethod
    def of(cls, c: Mapping[str, Any]) -> CheckRow:
        for suffix in ("rel", *ABSOLUTE_UNITS):
            if f"value_{suffix}" in c:
                return cls(_num(c.get(f"value_{suffix}")), _num(c.get(f"u_{suffix}")),
                           _num(c.get(f"tolerance_{suffix}")), _num(c.get(f"expected_{suffix}")),
                           suffix)
        return cls(None, None, None, None, "rel")

    def texts(self, signed: bool) -> tuple[str, str]:
        """(value ± U, tolerance or expected value) in the check's unit."""
        if self.suffix == "rel":
            unit = rel_unit(self.value, self.u, self.tolerance)
            vu = f"{_vu(self.value, self.u, unit, signed)} {unit.name}"
            tol = f"{_trim(self.tolerance * unit.scale)} {unit.name}" if self.tolerance else "—"
            return vu, tol
        name = ABSOLUTE_UNITS[self.suffix]
        vu = f"{_vu(self.value, self.u, None, signed)} {name}"
        if self.tolerance:
            return vu, f"{_trim(self.tolerance)} {name}"
        if self.expected is not None:
            return vu, f"expected {format_value_u(self.expected, self.u).value} {name}"
        return vu, "—"


def _specification(src: Sources) -> list[Any]:
    spec = src.get("specification") or src.procedure_file.get("specification")
    if not isinstance(spec, Mapping) or not spec.get("source"):
        return [Para("Specification: NOT IDENTIFIED. The procedure file names no source for "
                     "its tolerances (key specification.source); the checks below compare "
                     "with the procedure's numbers only.", "strong")]
    rows = [("Specification", _text(spec["source"]))]
    for key, text in (spec.get("definitions") or {}).items():
        name = QUANTITY_NAMES.get(str(key), QUANTITY_NAMES.get(str(key).rsplit("_", 1)[0],
                                                              _label(str(key))))
        rows.append((f"Definition: {name}", _text(text)))
    return [Fields(tuple(rows))]


def _conformity(src: Sources, checks: list[dict[str, Any]]) -> tuple[Any, ...]:
    rule = str(src.get("decision_rule") or (checks[0].get("rule") if checks else "simple"))
    kind = src.get("procedure") or ("drift-pulse" if src.get("drift") else "rate-ladder")
    blocks: list[Any] = [*_specification(src), Para(decision_rule_text(rule))]
    blocks.append(Para("Scope. " + _scope_line(src, checks, kind)))
    blocks.append(Para(
        "Measurement capability (RMG 63-2003): the expanded uncertainty of a check should not "
        f"exceed 0.2-0.3 of its tolerance; a ratio U/T ≤ {CAPABILITY_LIMIT:g} is marked met."))
    tol = (src.get("method", {}) or {}).get("tolerance") or src.procedure_file.get("tolerance")
    if isinstance(tol, Mapping) and tol:
        table = _tolerance_table(tol)
        if table.rows:
            blocks.append(table)
    if not checks:
        blocks.append(Para("The procedure states no tolerances: no conformity checks were "
                           "made and no statement of conformity is given for individual "
                           "values."))
        return tuple(blocks)
    consistency = [c for c in checks if check_class(c) == "consistency"]
    checks = [c for c in checks if check_class(c) != "consistency"]
    with_rate = all(_num(c.get("set_rate_dps")) is not None for c in checks)
    rows, notes = [], []
    for i, c in enumerate(checks, start=1):
        row = CheckRow.of(c)
        ratio = _num(c.get("capability_ratio"))
        if ratio is None and row.u is not None and row.tolerance:
            ratio = row.u / row.tolerance
        ok = c.get("capability_ok")
        if ok is None and ratio is not None:
            ok = ratio <= CAPABILITY_LIMIT
        if row.u is None or row.u <= 0:
            cap = "no U stated"  # a ratio of 0 would claim a capability nobody showed
        elif ratio is None:
            cap = "—"
        else:
            cap = f"{format_sig(ratio, 2)} " + ("met" if ok else "not met")
        inside = (row.value is not None and row.tolerance is not None
                  and abs(row.value) <= row.tolerance)
        label = verdict_label(c.get("verdict"), str(c.get("rule") or rule), inside)
        quantity = QUANTITY_NAMES.get(str(c.get("quantity")), _label(str(c.get("quantity"))))
        signed = str(c.get("quantity")) not in ("rate_instability", "intra_turn_instability",
                                                "intra_turn_instability_corrected")
        vu, tol_text = row.texts(signed)
        if check_class(c) == "not-assessed":
            unit = rel_unit(row.value, row.tolerance)
            limit = _num(c.get("upper_rel"))
            vu = present(row.value, row.u, unit.scale, resolved=False,
                         upper=limit).with_unit(unit.name) + " (timing floor)"
            cap = "—"
        elif _num(c.get("upper_rel")) is not None and row.suffix == "rel":
            unit = rel_unit(row.value, row.u, row.tolerance)
            vu += f"; 97.5 % limit {format_limit(_num(c['upper_rel']) * unit.scale)[0]}"
        rate = _num(c.get("set_rate_dps"))
        point = _rate(rate) if with_rate else (f"{_rate(rate)} °/s" if rate is not None else "—")
        rows.append((str(i), _text(c.get("axis")), point, quantity, vu, tol_text, cap, label))
        if label != "PASS" and c.get("reason"):
            notes.append(f"Check {i}: {label}: {c['reason']}")
        elif label != "PASS":
            notes.append(f"Check {i}: {label}.")
    header = ["#", "Axis", "Set rate, °/s" if with_rate else "Point", "Quantity", "Value ± U",
              "Tolerance T", "U/T (RMG 63)", "Verdict"]
    widths = [0.4, 0.8, 1.0, 2.2, 1.9, 1.3, 1.2, 1.4]
    align = "rlrlrrcc"
    if all(r[2] == "—" for r in rows):  # no check is tied to a rate
        rows = [r[:2] + r[3:] for r in rows]
        del header[2], widths[2]
        align = align[:2] + align[3:]
    if rows:
        blocks.append(Table(tuple(header), tuple(rows), widths=tuple(widths), align=align,
                            caption="Conformity with the specification's tolerances",
                            notes=tuple(notes)))
    if consistency:
        blocks.append(_consistency_table(consistency))
    return tuple(blocks)


def _consistency_table(checks: list[dict[str, Any]]) -> Table:
    """Physics cross-checks: they test the measurement, not the item, and are no part of
    the statement of conformity."""
    rows = []
    for c in checks:
        row = CheckRow.of(c)
        vu, expected = row.texts(signed=False)
        rows.append((_text(c.get("axis")), QUANTITY_NAMES.get(str(c.get("quantity")),
                                                             _label(str(c.get("quantity")))),
                     vu, expected, "consistent" if str(c.get("verdict")) == "pass"
                     else "NOT CONSISTENT"))
    return Table(("Axis", "Quantity", "Measured ± U", "Expected", "Result"), tuple(rows),
                 widths=(0.8, 2.2, 2.0, 2.0, 1.3), align="llrrc",
                 caption="Consistency checks (not part of the statement of conformity)",
                 notes=("A measured value against the value physics expects (the horizontal "
                        "Earth rate 15.041 °/h · cos(latitude)): consistent when they differ by "
                        "no more than U. An inconsistency puts the measurement in doubt (e.g. "
                        "k_as, levelling); it says nothing about the item's specification.",))


def _tolerance_table(tol: Mapping[str, Any]) -> Table:
    """The procedure's tolerances: rate bands (a band applies below its `below_dps`, in
    order) or one value per quantity with its unit in the key (`own_drift_dph: 0.5`)."""
    rows = []
    for quantity, bands in tol.items():
        words = str(quantity).split("_")
        if _num(bands) is not None and words[-1] in ABSOLUTE_UNITS:
            name = " ".join(words[:-1])
            rows.append((QUANTITY_NAMES.get("_".join(words[:-1]), name), "every measurement",
                         f"{_trim(_num(bands))} {ABSOLUTE_UNITS[words[-1]]}"))
            continue
        lo = 0.0
        for band in bands if isinstance(bands, list) else []:
            if not isinstance(band, Mapping):
                continue
            below, rel = _num(band.get("below_dps")), _num(band.get("rel"))
            if below is not None:
                where = (f"{lo:g} ≤ |ω_set| < {below:g} °/s" if lo else
                         f"|ω_set| < {below:g} °/s")
                lo = below
            else:
                where = f"|ω_set| ≥ {lo:g} °/s" if lo else "every rate"
            if rel is None:
                continue
            unit = rel_unit(rel)
            text = f"{_trim(rel * unit.scale)} {unit.name}"
            if unit is not PERCENT:
                text += f" ({_trim(rel * 100)} %)"
            rows.append((QUANTITY_NAMES.get(quantity, _label(quantity)), where, text))
    return Table(("Quantity", "Applies to", "Tolerance T"), tuple(rows),
                 widths=(2.5, 2.5, 2.0), align="llr",
                 caption="Tolerances stated in the procedure file")


def _records(src: Sources) -> tuple[Any, ...]:
    files = [f for f in src.get("raw_files", []) or [] if isinstance(f, dict)]
    hashed_here = False
    if not files and src.run_path is not None and (src.run_path / "raw").is_dir():
        hashed_here = True
        for p in sorted((src.run_path / "raw").rglob("*")):
            if p.is_file():
                files.append({"path": p.relative_to(src.run_path).as_posix(),
                              "sha256": sha256_file(p), "bytes": p.stat().st_size})
    inputs = []
    if src.run_path is not None:
        for name in ("procedure.yaml", "stand.yaml", "meta.json", "events.jsonl"):
            p = src.run_path / name
            if p.is_file():
                inputs.append({"path": name, "sha256": sha256_file(p), "bytes": p.stat().st_size})
    blocks: list[Any] = [Para(
        "SHA-256 digests of the raw data as received from the instruments; anyone holding the "
        "run directory can check that the results above were computed from these bytes "
        "(`bench analyze RUN_DIR` recomputes them).")]
    if files:
        blocks.append(_hash_table(files, "Raw data files" + (
            " (hashed when this certificate was issued)" if hashed_here else "")))
    else:
        blocks.append(Para("No raw data files were recorded.", "note"))
    if inputs:
        blocks.append(_hash_table(inputs, "Run records (inputs as used and the event log; "
                                          "the event log's digest is at the time of issue)"))
    return tuple(blocks)


def _hash_table(files: Sequence[Mapping[str, Any]], caption: str) -> Table:
    rows = tuple((_text(f.get("path")), f"{int(f['bytes']):,}".replace(",", " ")
                  if _num(f.get("bytes")) is not None else "—", _text(f.get("sha256")))
                 for f in files)
    return Table(("File", "Bytes", "SHA-256"), rows, widths=(2.6, 1.0, 5.0), align="lrl",
                 caption=caption, mono=True)


def _signatures(cert: Mapping[str, Any], issue: Issue) -> tuple[Any, ...]:
    """Named signatories with their functions (the lab's settings); the one who authorises
    the issue dates it, and that date is the date of issue."""
    signers = cert.get("signatories") or cert.get("signers")
    pairs: list[tuple[str, str]] = []
    authoriser = ""
    if isinstance(signers, list) and signers:
        for sg in signers:
            if not isinstance(sg, Mapping):
                pairs.append((str(sg), ""))
                continue
            function = str(sg.get("function") or sg.get("role") or "")
            name = str(sg.get("name") or "")
            pairs.append((function, name))
            if sg.get("authorises") or "authoris" in function.lower():
                authoriser = authoriser or f"{name}, {function}"
    else:
        pairs = [("Calibration performed by", ""), ("Reviewed and authorised by", "")]
    text = (f"Date of issue: {issue.issue_date}, the date on which this certificate was "
            "authorised for issue" + (f" by {authoriser}." if authoriser else "."))
    if issue.replaces:
        text += (f" Revision {issue.revision}: it replaces certificate {issue.replaces}, "
                 "which is withdrawn.")
    return (Para(text), Signatures(tuple(pairs)))
