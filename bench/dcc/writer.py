"""result.json (plus the run directory) -> a PTB DCC 3.3.0 document (lxml tree).

Every number comes from result.json unrounded (see bench.dcc.xml.dec); what the result
lacks comes from the run directory's records or the laboratory's settings, never invented.
A required DCC field nobody recorded says "not recorded" in its text, so the gap shows.
Layout (docs/dcc.md walks through it):

    administrativeData   software, refTypeDefinitions, core data (ids, dates, location),
                         the item with its serial, laboratory, responsible persons,
                         customer, statements (decision rule and overall conformity,
                         location, raw-data SHA-256 digests, simulated stand)
    measurementResults   methods (docs/method.md sections), conditions, then one
                         measurementResult per axis (rate ladder) or one for the
                         platform (drift pulse); each check's conformity sits on the
                         quantity it judges
    document             certificate.pdf, the human-readable certificate
"""

from __future__ import annotations

import base64
import datetime as dt
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from lxml import etree

import bench
from bench.certificate import methods
from bench.certificate.build import Sources, decision_rule_text, issued_number
from bench.dcc import units as U
from bench.dcc import vocab as V
from bench.dcc.settings import LabSettings
from bench.dcc.validate import SCHEMA_LOCATION
from bench.dcc.xml import (
    DCC_NS,
    XSI_NS,
    el,
    ident,
    list_quantity,
    name,
    num,
    quantity,
    rate_token,
    si_real,
    text_el,
)

NOT_RECORDED = "not recorded"
PDF_NAME = "certificate.pdf"
UNKNOWN_COUNTRY = "ZZ"   # ISO 3166-1 user-assigned code: the laboratory did not configure one
QUANTITY_TITLES = {
    "rate_error": "per-turn rate error",
    "rate_instability": "per-turn rate instability",
    "intra_turn_instability": "intra-turn instability",
    "intra_turn_instability_corrected": "intra-turn instability, floor-corrected",
    "own_drift": "own drift",
    "apparent_drift": "apparent drift",
    "earth_horizontal_rate": "horizontal Earth rate",
    "azimuth": "platform azimuth",
}
ILAC_G8 = "ILAC-G8:09/2019"
RULE_REFERENCE = {"simple": "4.2.1 simple acceptance (shared risk)",
                  "guard-band": "4.2.2 guarded acceptance, guard band w = U"}

# the method document's sections each procedure uses (bench/method.md = docs/method.md)
A_SECTIONS = ("A1", "A2", "A3", "A4", "A5", "A6")
B_SECTIONS = ("B",)
METHOD_DOC = "docs/method.md"


def method_sections() -> tuple[bytes, dict[str, tuple[str, str]]]:
    """The method document as shipped, and section -> (heading, text) from its headings
    (`### A1. ...`, `## B. ...`)."""
    data = resources.files("bench").joinpath("method.md").read_bytes()
    sections: dict[str, tuple[str, str]] = {}
    current: str | None = None
    for line in data.decode("utf-8").splitlines():
        m = re.match(r"#{2,3} ([A-Z]\d?)\. (.*)", line)
        if m:
            current = m.group(1)
            sections[current] = (m.group(2).strip(), "")
        elif current is not None and not line.startswith("#"):
            head, body = sections[current]
            sections[current] = (head, (body + " " + line.strip()).strip())
    return data, sections


@dataclass
class _Checks:
    """The run's checks, each handed to the quantity it judges (or left for statements)."""

    items: list[dict[str, Any]]
    used: set[int] = field(default_factory=set)

    def take(self, axis: str | None, rate: float | None, quantity_key: str
             ) -> list[tuple[int, dict[str, Any]]]:
        found = []
        for i, c in enumerate(self.items):
            if i in self.used or str(c.get("quantity")) != quantity_key:
                continue
            if axis is not None and c.get("axis") not in (axis, None):
                continue
            c_rate = num(c.get("set_rate_dps"))
            if (rate is None) != (c_rate is None) or (rate is not None and c_rate != rate):
                continue
            self.used.add(i)
            found.append((i, c))
        return found

    def rest(self) -> list[tuple[int, dict[str, Any]]]:
        return [(i, c) for i, c in enumerate(self.items) if i not in self.used]


def _checks(src: Sources) -> list[dict[str, Any]]:
    checks = src.result.get("checks")
    return [c for c in checks if isinstance(c, dict)] if isinstance(checks, list) else []


def _date(stamp: Any) -> str | None:
    if not stamp:
        return None
    try:
        t = dt.datetime.fromisoformat(str(stamp).replace("Z", "+00:00"))
    except ValueError:
        return None
    if t.tzinfo is not None:
        t = t.astimezone(dt.UTC)
    return t.date().isoformat()


def _event(src: Sources, kind: str, last: bool = False) -> str | None:
    found = [e.get("utc") for e in src.events if e.get("event") == kind]
    return (found[-1] if last else found[0]) if found else None


def _stand(src: Sources) -> dict[str, Any]:
    stand = dict(src.stand_file.get("stand", {}) or {})
    stand.update({k: v for k, v in (src.get("stand", {}) or {}).items() if v is not None})
    return stand


# -- the document --------------------------------------------------------------------------

@dataclass(frozen=True)
class DccInputs:
    """What the writer reads: the result, its run directory, the lab's settings."""

    result: dict[str, Any]
    run_path: Path | None = None
    lab: LabSettings = LabSettings()
    issued: dt.date | None = None
    embed_pdf: bool = True


def build_dcc(inputs: DccInputs) -> etree._ElementTree:
    """The DCC as an lxml tree (unsigned); `bench.dcc.validate` checks it."""
    src = Sources.load(inputs.result, inputs.run_path)
    kind = src.get("procedure") or src.procedure_file.get("procedure") or (
        "drift-pulse" if src.get("drift") else "rate-ladder")
    checks = _Checks(_checks(src))
    root = el(None, "digitalCalibrationCertificate", schemaVersion="3.3.0")
    root.set(f"{{{XSI_NS}}}schemaLocation", SCHEMA_LOCATION)
    issue = (inputs.issued or dt.datetime.now(dt.UTC).date()).isoformat()
    _administrative(el(root, "administrativeData"), src, inputs.lab, kind, issue)
    results = el(root, "measurementResults")
    _common_results(results, src, kind)
    if kind == "drift-pulse":
        _drift(results, src, checks)
    else:
        _ladder(results, src, checks)
    if results.find(f"{{{DCC_NS}}}measurementResult") is None:    # the DCC needs one
        mr = el(results, "measurementResult", id="noResults")
        name(mr, "No results")
        r = el(el(mr, "results"), "result")
        name(r, "No results")
        text_el(el(r, "data"), "text", "result.json carries no results: nothing was measured "
                "to completion, or its results were malformed.")
    _leftover_checks(root, src, checks)
    pdf = inputs.run_path / PDF_NAME if inputs.run_path is not None else None
    if inputs.embed_pdf and pdf is not None and pdf.is_file():
        doc = el(root, "document", id="certificatePdf")
        name(doc, "Calibration certificate, human-readable (PDF, same content)")
        el(doc, "fileName", PDF_NAME)
        el(doc, "mimeType", "application/pdf")
        el(doc, "dataBase64", base64.b64encode(pdf.read_bytes()).decode("ascii"))
    return etree.ElementTree(root)


# -- administrative data -------------------------------------------------------------------

def _administrative(adm: etree._Element, src: Sources, lab: LabSettings, kind: str,
                    issue: str) -> None:
    cert = src.get("certificate", {}) or src.procedure_file.get("certificate", {}) or {}
    soft = el(adm, "dccSoftware")
    versions = dict.fromkeys([bench.__version__, str(src.meta.get("bench_version") or
                                                     bench.__version__)])
    for i, version in enumerate(versions):
        sw = el(soft, "software")
        name(sw, "ratebench (rate-table attestation bench)")
        el(sw, "release", version)
        el(sw, "type", "application")
        text_el(sw, "description", "wrote this DCC" if i == 0 else "ran the measurement")
    defs = el(adm, "refTypeDefinitions")
    for ns in V.NAMESPACES:
        d = el(defs, "refTypeDefinition")
        name(d, ns.name)
        text_el(d, "description", ns.description)
        el(d, "namespace", ns.prefix)
        el(d, "link", ns.link)
    core = el(adm, "coreData")
    country = (lab.country_code or cert.get("country_code")
               or dict(lab.laboratory.location.fields).get("countryCode")
               if lab.laboratory else lab.country_code or cert.get("country_code"))
    el(core, "countryCodeISO3166_1", str(country or UNKNOWN_COUNTRY))
    el(core, "usedLangCodeISO639_1", "en")
    el(core, "mandatoryLangCodeISO639_1", "en")
    el(core, "uniqueIdentifier", issued_number(src))
    ids = el(core, "identifications")
    run_dir = src.get("run_dir") or (src.run_path.name if src.run_path else None)
    if run_dir:
        idn = el(ids, "identification", ref_type=V.RUN_DIRECTORY)
        el(idn, "issuer", "calibrationLaboratory")
        el(idn, "value", str(run_dir))
        name(idn, "Run directory (raw data and result.json)")
    title = src.get("title") or src.procedure_file.get("title")
    if title:
        idn = el(ids, "identification")
        el(idn, "issuer", "calibrationLaboratory")
        el(idn, "value", str(title))
        name(idn, "Title of the work")
    if not len(ids):
        core.remove(ids)
    dates = src.get("dates", {}) or {}
    begin = (_date(dates.get("started_utc")) or _date(_event(src, "session_start"))
             or _date(dates.get("created_utc")) or _date(src.meta.get("created_utc")) or issue)
    end = (_date(dates.get("completed_utc")) or _date(_event(src, "completed", last=True))
           or begin)
    el(core, "beginPerformanceDate", begin)
    el(core, "endPerformanceDate", end)
    el(core, "performanceLocation", lab.performance_location
       or str(cert.get("performance_location") or "laboratory"))
    el(core, "issueDate", issue)
    _item(el(adm, "items"), src, kind)
    labx = el(adm, "calibrationLaboratory")
    if lab.laboratory and lab.laboratory.code:
        el(labx, "calibrationLaboratoryCode", lab.laboratory.code)
    contact = el(labx, "contact")
    lab_name = (lab.laboratory.name if lab.laboratory else None) or cert.get("laboratory")
    name(contact, str(lab_name or f"laboratory {NOT_RECORDED}"))
    if lab.laboratory and lab.laboratory.email:
        el(contact, "eMail", lab.laboratory.email)
    if lab.laboratory and lab.laboratory.phone:
        el(contact, "phone", lab.laboratory.phone)
    _location(contact, lab.laboratory.location.fields if lab.laboratory else ())
    persons = el(adm, "respPersons")
    people = [(p.name, p.role, p.main_signer) for p in lab.persons]
    if not people:
        signers = cert.get("signers")
        for s in signers if isinstance(signers, list) else []:
            if isinstance(s, Mapping):
                people.append((str(s.get("name") or ""), str(s.get("role") or "") or None,
                               bool(s.get("main_signer"))))
    for person_name, role, main in people or [("", "Calibration performed by", False)]:
        rp = el(persons, "respPerson")
        name(el(rp, "person"), person_name or f"name {NOT_RECORDED} (signs the PDF by hand)")
        if role:
            el(rp, "role", role)
        if main:
            el(rp, "mainSigner", "true")
    customer = el(adm, "customer")
    name(customer, str(cert.get("customer") or f"customer {NOT_RECORDED}"))
    where = cert.get("customer_location")
    _location(customer, (("further", str(where)),) if where else ())
    _statements(el(adm, "statements"), src, kind, country)


def _location(parent: etree._Element, fields: Sequence[tuple[str, str]]) -> None:
    loc = el(parent, "location")
    for tag, value in fields or (("further", f"address {NOT_RECORDED}"),):
        if tag == "further":
            text_el(loc, tag, value)
        else:
            el(loc, tag, value)


def _item(items: etree._Element, src: Sources, kind: str) -> None:
    stand = _stand(src)
    item = el(items, "item", id="item")
    what = "gyro-platform test stand" if kind == "drift-pulse" else "rotary rate table"
    name(item, " ".join(str(x) for x in (stand.get("maker"), stand.get("model")) if x)
         or f"{what} ({NOT_RECORDED})")
    axes = ", ".join(str(a) for a in (src.get("axes") or (src.get("drift") or {}).get("axes")
                                      or {}))
    text = f"Item calibrated: {what}" + (f"; axes {axes}" if axes else "") + "."
    if stand.get("simulated"):
        text += (" SIMULATED stand: instrument twins on real channels; these results "
                 "describe no physical item.")
    if stand.get("file"):
        text += f" Stand file {stand['file']} (SHA-256 {stand.get('sha256', NOT_RECORDED)})."
    text_el(item, "description", text)
    if stand.get("maker"):
        name(el(item, "manufacturer"), str(stand["maker"]))
    if stand.get("model"):
        el(item, "model", str(stand["model"]))
    ids = el(item, "identifications")
    idn = el(ids, "identification")
    el(idn, "issuer", "manufacturer")
    el(idn, "value", str(stand.get("serial") or NOT_RECORDED))
    name(idn, "Serial number")


def _statement(parent: etree._Element, ref_type: str | None, declaration: str,
               **kw: Any) -> etree._Element:
    st = el(parent, "statement", ref_type=ref_type, id=kw.get("sid"))
    if kw.get("title"):
        name(st, kw["title"])
    for norm in kw.get("norms", ()):
        el(st, "norm", norm)
    for ref in kw.get("references", ()):
        el(st, "reference", ref)
    text_el(st, "declaration", declaration)
    if kw.get("conformity"):
        el(st, "conformity", kw["conformity"])
    return st


def _statements(sts: etree._Element, src: Sources, kind: str, country: Any) -> None:
    for i, text in enumerate(methods.STATEMENTS):
        if kind == "drift-pulse" and text.startswith("Relative values"):
            continue
        text = (text.replace("as identified in section 1", "identified under items")
                .replace("printed in % or in ppm (1 ppm = 0.0001 %) as the column header "
                         "states", "given here as plain fractions (unit \\one); the PDF "
                         "prints them in % or ppm"))
        _statement(sts, None, text, norms=("ISO/IEC 17025:2017",),
                   references=("7.8",) if i else ("7.8.2.1 l)",))
    verdict = str(src.get("verdict") or "incomplete").lower()
    rule = str(src.get("decision_rule") or "simple")
    overall = {"pass": "pass", "fail": "fail"}.get(verdict)
    n = len(_checks(src))
    text = (f"Overall statement of conformity: {verdict.upper()} ({n} check(s), each stated "
            "with the quantity it judges). " + decision_rule_text(rule))
    _statement(sts, V.CONFORMITY, text, sid="overallConformity", title="Conformity",
               norms=(ILAC_G8,), references=(RULE_REFERENCE.get(rule, rule),),
               conformity=overall)
    stand = _stand(src)
    if stand.get("location"):
        st = _statement(sts, V.LOCATION, "Location of the item during the calibration.")
        loc = el(st, "location")
        text_el(loc, "further", str(stand["location"]))
    if stand.get("simulated"):
        _statement(sts, V.SIMULATED, "SIMULATED stand: every instrument was a simulated "
                   "twin on a real channel; the results describe no physical item.")
    if not country:
        _statement(sts, V.COUNTRY_UNKNOWN, "The laboratory configured no country: the "
                   f"country code {UNKNOWN_COUNTRY} (ISO 3166-1 user-assigned) stands for "
                   "'not recorded'.")
    _digests(sts, src)


def _digests(sts: etree._Element, src: Sources) -> None:
    files = [f for f in src.get("raw_files", []) or [] if isinstance(f, Mapping)]
    if not files and src.run_path is not None and (src.run_path / "raw").is_dir():
        from bench.journal import sha256_file

        files = [{"path": p.relative_to(src.run_path).as_posix(), "sha256": sha256_file(p),
                  "bytes": p.stat().st_size}
                 for p in sorted((src.run_path / "raw").rglob("*")) if p.is_file()]
    if not files:
        _statement(sts, V.RAW_DIGESTS, "No raw data files were recorded.")
        return
    st = _statement(sts, V.RAW_DIGESTS, "SHA-256 digests of the raw data as received from "
                    "the instruments (path in the run directory, then the digest in hex); "
                    "`bench analyze RUN_DIR` recomputes every result from these bytes.",
                    title="Raw data files")
    data = el(st, "data")
    for f in files:
        t = el(data, "text", ref_type=V.SHA256)
        name(t, str(f.get("path") or NOT_RECORDED))
        el(t, "content", str(f.get("sha256") or NOT_RECORDED))
        if num(f.get("bytes")) is not None:
            el(t, "content", f"{int(num(f.get('bytes')) or 0)} bytes")


# -- methods and conditions ----------------------------------------------------------------

def _common_results(results: etree._Element, src: Sources, kind: str) -> None:
    used = el(results, "usedMethods")
    document, sections = method_sections()
    m = el(used, "usedMethod", id="methodDocument", ref_type=V.METHOD)
    name(m, f"ratebench method document ({METHOD_DOC}), as shipped with this release")
    desc = text_el(m, "description", methods.B_REFERENCE if kind == "drift-pulse"
                   else methods.A_REFERENCE)
    f = el(desc, "file")
    el(f, "fileName", "method.md")
    el(f, "mimeType", "text/markdown")
    el(f, "dataBase64", base64.b64encode(document).decode("ascii"))
    for sec in B_SECTIONS if kind == "drift-pulse" else A_SECTIONS:
        heading, text = sections.get(sec, (f"section {sec}", f"see {METHOD_DOC}"))
        m = el(used, "usedMethod", id=ident("method", sec), ref_type=V.METHOD)
        name(m, f"{METHOD_DOC} {sec}: {heading}")
        text_el(m, "description", text or f"see {METHOD_DOC}")
        el(m, "reference", f"{METHOD_DOC} section {sec} (embedded above)")
    pf = src.get("procedure_file", {}) or {}
    proc_name = pf.get("name") or src.meta.get("procedure_name")
    if proc_name:
        m = el(used, "usedMethod", id="procedureFile")
        name(m, f"Procedure file {proc_name}")
        text_el(m, "description", f"The procedure as run, SHA-256 "
                f"{pf.get('sha256') or src.meta.get('procedure_sha256') or NOT_RECORDED}; "
                f"settings: {_flat(src.get('method', {}) or {})}.")
    m = el(used, "usedMethod", id="uncertaintyMethod", ref_type=V.UNCERTAINTY)
    name(m, "Expanded measurement uncertainty")
    text_el(m, "description", "Every U is the standard uncertainty multiplied by the "
            "coverage factor k = 2, which for a normal distribution gives a coverage "
            "probability of about 95 %. Values and U are given unrounded as computed; the "
            "PDF prints them rounded (U to two significant digits).")
    el(m, "norm", "JCGM 100:2008 (GUM)")
    sw = el(results, "usedSoftware")
    s = el(sw, "software")
    name(s, "ratebench analysis")
    el(s, "release", bench.__version__)
    el(s, "type", "application")
    equipment = _equipment(src)
    if equipment is not None:
        results.append(equipment)
    cond = src.get("conditions") or src.procedure_file.get("conditions") or {}
    if isinstance(cond, Mapping) and cond:
        conds = el(results, "influenceConditions")
        for key, value in cond.items():
            _condition(conds, str(key), value)


def _flat(d: Mapping[str, Any]) -> str:
    return "; ".join(f"{k} = {v}" for k, v in d.items() if k != "tolerance") or NOT_RECORDED


def _equipment(src: Sources) -> etree._Element | None:
    ids = src.get("instruments", {}) or {}
    if not isinstance(ids, Mapping) or not ids:
        return None
    eq = etree.Element(f"{{{DCC_NS}}}measuringEquipments")
    for axis, roles in ids.items():
        for role, identity in (roles or {}).items():
            me = el(eq, "measuringEquipment", id=ident("eq", axis, role),
                    ref_type=V.NORMAL_USED if role == "counter" else None)
            name(me, f"Axis {axis}: {role}")
            text_el(me, "description", f"Identity as reported: {identity}")
    return eq if len(eq) else None


_NUMBER = r"[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?"
_CONDITION_UNITS = {"c": (U.CELSIUS, V.TEMPERATURE, V.TEMPERATURE_MIN, V.TEMPERATURE_MAX),
                    "pct": (U.PERCENT, V.HUMIDITY, V.HUMIDITY_MIN, V.HUMIDITY_MAX),
                    "hpa": (U.HECTOPASCAL, V.CONDITION, None, None)}


def _condition(conds: etree._Element, key: str, value: Any) -> None:
    """A recorded condition: '20 +/- 2' under `temperature_c` becomes 18 ... 22 degC; text
    that is not a number with its unit stays text (it is never guessed)."""
    suffix = key.rsplit("_", 1)[-1].lower() if "_" in key else ""
    text = str(value)
    if key.lower().startswith("humid") and text.strip().endswith("%"):
        suffix, text = "pct", text.strip()[:-1]
    spec = _CONDITION_UNITS.get(suffix)
    label = key.rsplit("_", 1)[0] if spec else key
    c = el(conds, "influenceCondition", id=ident("cond", key),
           ref_type=spec[1] if spec else V.CONDITION)
    name(c, label.replace("_", " ").capitalize())
    text_el(c, "description", f"As recorded in the procedure file: {key}: {value}")
    data = el(c, "data")
    m = re.fullmatch(rf"\s*({_NUMBER})\s*(?:(?:\+/-|±)\s*({_NUMBER}))?\s*", text)
    if spec is None or m is None:
        text_el(data, "text", str(value))
        return
    unit, _, low_ref, high_ref = spec
    centre, half = float(m.group(1)), num(m.group(2))
    if half is not None and low_ref and high_ref:
        quantity(data, None, "minimum", low_ref, centre - half, unit)
        quantity(data, None, "maximum", high_ref, centre + half, unit)
    else:
        quantity(data, None, "stated value", V.NOMINAL, centre, unit)


# -- conformity ----------------------------------------------------------------------------

def _conformity(q: etree._Element, found: list[tuple[int, dict[str, Any]]], unit: str) -> None:
    """Each check as measurementMetaData on the quantity it judges (good-practice layout)."""
    if not found:
        return
    meta = el(q, "measurementMetaData")
    for i, c in found:
        rule = str(c.get("rule") or "simple")
        verdict = {"pass": "pass", "fail": "fail"}.get(str(c.get("verdict")).lower())
        md = el(meta, "metaData", id=ident("check", i + 1), ref_type=V.CONFORMITY)
        name(md, f"Check {i + 1}: conformity with the tolerance")
        if rule in RULE_REFERENCE:
            el(md, "norm", ILAC_G8)
            el(md, "reference", RULE_REFERENCE[rule])
        text_el(md, "declaration", f"{str(c.get('verdict') or '').upper()}: "
                f"{c.get('reason') or 'no reason recorded'}. Decision rule: {rule}.")
        if verdict:
            el(md, "conformity", verdict)
        suffix = next((s for s in ("rel", "dph", "dps", "deg", "s") if f"value_{s}" in c), "rel")
        tol, expected = num(c.get(f"tolerance_{suffix}")), num(c.get(f"expected_{suffix}"))
        cunit = U.BY_SUFFIX.get(suffix, unit)
        data = el(md, "data")
        cid = ident("check", i + 1)
        if tol is not None:
            quantity(data, f"{cid}_low", "lower acceptance limit (-T)", V.LIMIT_LOW, -tol, cunit)
            quantity(data, f"{cid}_high", "upper acceptance limit (+T)", V.LIMIT_HIGH, tol,
                     cunit)
        if expected is not None:
            quantity(data, f"{cid}_expected", "expected value", V.REFERENCE, expected, cunit)
        if not len(data):
            md.remove(data)


def _leftover_checks(root: etree._Element, src: Sources, checks: _Checks) -> None:
    """A check whose quantity the writer did not place still gets its statement."""
    rest = checks.rest()
    if not rest:
        return
    sts = root.find(f"{{{DCC_NS}}}administrativeData/"
                    f"{{{DCC_NS}}}statements")
    for i, c in rest:
        verdict = {"pass": "pass", "fail": "fail"}.get(str(c.get("verdict")).lower())
        _statement(sts, V.CONFORMITY, f"Check {i + 1} ({c.get('axis')}, "
                   f"{c.get('quantity')}): {str(c.get('verdict') or '').upper()}: "
                   f"{c.get('reason') or 'no reason recorded'}",
                   sid=ident("check", i + 1), conformity=verdict)


# -- rate ladder ---------------------------------------------------------------------------

def _ladder(results: etree._Element, src: Sources, checks: _Checks) -> None:
    axes = src.get("axes", {}) or {}
    for axis, ax in axes.items():
        if not isinstance(ax, Mapping):
            continue
        mr = el(results, "measurementResult", id=ident("axis", axis), ref_id="item")
        name(mr, f"Axis {axis}: per-turn rate, FOG cross-calibration and intra-turn "
                 "instability (rate ladder)")
        text_el(mr, "description", "Per commanded rate and direction (signed: + is the "
                "table's positive sense). Relative values are plain fractions of the "
                "commanded rate (unit \\one).")
        res = el(mr, "results")
        for i, r in enumerate(ax.get("rates") or []):
            if isinstance(r, Mapping):
                _rate_result(res, axis, i, r, checks)
        for i, p in enumerate(ax.get("pairs") or []):
            if isinstance(p, Mapping):
                _pair_result(res, axis, i, p)
        floor = ax.get("noise_floor") or {}
        sd = num(floor.get("sample_std_dps")) if isinstance(floor, Mapping) else None
        if sd is not None:
            r = el(res, "result", id=ident("floor", axis), ref_type=V.FOG_FLOOR)
            name(r, f"Axis {axis}: FOG noise floor at rest (docs/method.md A5)")
            text_el(r, "description", f"{floor.get('source', 'record at rest')}; "
                    f"{floor.get('samples', NOT_RECORDED)} samples over "
                    f"{floor.get('duration_s', NOT_RECORDED)} s.")
            quantity(el(r, "data"), ident("q", axis, "floor_std"), "standard deviation of "
                     "one FOG sample at rest", V.FOG_FLOOR, sd, U.DEG_PER_S,
                     label=f"axes.{axis}.noise_floor.sample_std_dps")
        if not len(res):
            r = el(res, "result")
            name(r, f"Axis {axis}: no results")
            text_el(el(r, "data"), "text", "Nothing was measured to completion on this axis.")


def _per_turn_u(r: Mapping[str, Any], rates: list[float]) -> list[float] | None:
    """U (k = 2) of each per-turn rate, docs/method.md A1: dw/w = dT/T with T = 360/|w|, combined
    with the counter timebase: U = 2 |w| sqrt((u_T |w| / 360)^2 + u_tb^2)."""
    b = r.get("rate_error_budget")
    if not isinstance(b, Mapping) or num(b.get("period_u_s")) is None:
        return None
    u_t, u_tb = num(b.get("period_u_s")) or 0.0, num(b.get("timebase_u_rel")) or 0.0
    return [2 * abs(w) * ((u_t * abs(w) / 360.0) ** 2 + u_tb ** 2) ** 0.5 for w in rates]


def _rate_result(res: etree._Element, axis: str, i: int, r: Mapping[str, Any],
                 checks: _Checks) -> None:
    w_set = num(r.get("set_rate_dps"))
    tok = rate_token(w_set)
    path = f"axes.{axis}.rates[{i}]"
    rid = ident("r", axis, tok)
    result = el(res, "result", id=rid, ref_type=V.MEASURED)
    name(result, f"Axis {axis}, set rate {w_set:+g} deg/s" if w_set is not None
         else f"Axis {axis}, rate {i + 1}")
    verdict = r.get("verdict")
    if verdict:
        text_el(result, "description", f"Verdict at this rate: {str(verdict).upper()}.")
    data = el(result, "data")

    def q(key: str, title: str, ref: str, unit: str, u_key: str | None = None,
          u: float | None = None, note: str | None = None, check: str | None = None,
          value: float | None = None, label: str | None = None) -> etree._Element | None:
        v = value if value is not None else num(r.get(key))
        if v is None:
            return None
        uu = u if u is not None else (num(r.get(u_key)) if u_key else None)
        if uu is None and u_key is not None:
            note = (note + " " if note else "") + "U not stated in result.json."
        node = quantity(data, ident(rid, key), title, ref, v, unit, uu,
                        label=label or f"{path}.{key}", note=note)
        if check:
            _conformity(node, checks.take(axis, w_set, check), unit)
        return node

    q("set_rate_dps", "commanded (set) rate", f"{V.NOMINAL} {V.SET_RATE}", U.DEG_PER_S)
    q("turns", "whole turns timed", V.TURNS, U.ONE)
    cr = [v for v in (num(x) for x in r.get("counter_rate_dps") or []) if v is not None]
    mean = num(r.get("mean_rate_dps"))
    if mean is None and cr:
        mean = sum(cr) / len(cr)
    eu = num(r.get("rate_error_u_rel"))
    if mean is not None:
        q("mean_rate_dps", "mean rate over the turns (counter, docs/method.md A2)", V.MEASURED,
          U.DEG_PER_S, value=mean, u=eu * abs(w_set) if eu is not None and w_set else None,
          note="U = U(rate error) x |set rate|.")
    q("rate_error_rel", "per-turn rate error (mean - set) / |set| (docs/method.md A2 eq. 1, "
      "signed)", f"{V.ERROR} {V.RATE_ERROR}", U.ONE, "rate_error_u_rel", check="rate_error")
    q("rate_instability_rel", "per-turn rate instability, relative std of the per-turn rates "
      "(docs/method.md A2 eq. 2)", V.RATE_INSTABILITY, U.ONE, "rate_instability_u_rel",
      check="rate_instability")
    q("rate_instability_floor_rel", "timing floor of the instability (counter and zero-mark "
      "timing alone, docs/method.md A1)", V.TIMING_FLOOR, U.ONE)
    if cr:
        us = _per_turn_u(r, cr)
        list_quantity(data, ident(rid, "counter_rate_dps"), "per-turn rates from the counter, "
                      "in turn order (docs/method.md A1)", f"{V.MEASURED} {V.PER_TURN}", cr,
                      U.DEG_PER_S, us, note=None if us is not None else
                      "U not stated: result.json carries no timing budget for this rate.")
    intra = r.get("intra_turn") or {}
    q("intra_turn_instability_rel", "intra-turn instability std(random part) / |set| at the "
      "FOG bandwidth (docs/method.md A5)", V.INTRA_TURN, U.ONE, "intra_turn_instability_u_rel",
      check="intra_turn_instability")
    if isinstance(intra, Mapping) and num(intra.get("floor_rel")) is not None:
        q("floor_rel", "FOG noise floor, relative to |set| (docs/method.md A5)", V.FOG_FLOOR, U.ONE,
          value=num(intra.get("floor_rel")), label=f"{path}.intra_turn.floor_rel")
    upper = num(intra.get("corrected_upper_rel")) if isinstance(intra, Mapping) else None
    resolved = intra.get("resolved") if isinstance(intra, Mapping) else None
    q("intra_turn_instability_corrected_rel", "intra-turn instability with the FOG noise "
      "floor removed in quadrature (docs/method.md A5)", V.INTRA_TURN_CORRECTED, U.ONE,
      None if upper is not None else "intra_turn_instability_corrected_u_rel",
      u=num(r.get("intra_turn_instability_corrected_u_rel")),
      note=("not resolved above the FOG noise floor; read the upper limit" if resolved is False
            else None), check="intra_turn_instability_corrected")
    if upper is not None:
        q("corrected_upper_rel", "upper limit (k = 2) of the floor-corrected intra-turn "
          "instability", V.INTRA_TURN_UPPER, U.ONE, value=upper,
          label=f"{path}.intra_turn.corrected_upper_rel")
    _budget(data, ident(rid, "budget"), "uncertainty budget of the rate error: standard "
            "uncertainties (k = 1) relative to |set|; U = 2 sqrt(sum u^2) (docs/method.md "
            "A1-A2)", r.get("rate_error_budget"), f"{path}.rate_error_budget",
            (("timing_u_rel", "zero-mark timing"), ("timebase_u_rel", "counter timebase"),
             ("repeatability_u_rel", "repeatability (Type A)")), U.ONE)
    _averaged(data, rid, path, intra)
    _systematic(data, rid, path, r.get("systematic") or {})


def _budget(data: etree._Element, lid: str, title: str, budget: Any, path: str,
            terms: Sequence[tuple[str, str]], unit: str) -> None:
    """The standard uncertainties behind a U, one quantity per source (no U of their own)."""
    if not isinstance(budget, Mapping):
        return
    found = [(k, label, num(budget.get(k))) for k, label in terms]
    found = [(k, label, v) for k, label, v in found if v is not None]
    if not found:
        return
    lst = el(data, "list", id=lid, ref_type=V.BUDGET)
    name(lst, title)
    for key, label, v in found:
        quantity(lst, ident(lid, key), f"u({label})", V.STANDARD_UNCERTAINTY, v, unit,
                 label=f"{path}.{key}")


def _averaged(data: etree._Element, rid: str, path: str, intra: Any) -> None:
    rows = intra.get("averaged") if isinstance(intra, Mapping) else None
    for j, a in enumerate(rows or []):
        if not isinstance(a, Mapping) or num(a.get("angle_deg")) is None:
            continue
        lst = el(data, "list", id=ident(rid, "avg", f"{num(a['angle_deg']):g}"),
                 ref_type=V.AVERAGED)
        name(lst, f"random part averaged over {num(a['angle_deg']):g} deg of table angle "
                  "(docs/method.md A5)")
        p = f"{path}.intra_turn.averaged[{j}]"
        quantity(lst, None, "window", V.WINDOW, num(a["angle_deg"]) or 0.0, U.DEG,
                 label=f"{p}.angle_deg")
        v = num(a.get("instability_rel"))
        if v is not None:
            uu = num(a.get("u_rel"))
            quantity(lst, ident(rid, "avg", f"{num(a['angle_deg']):g}", "instability_rel"),
                     "instability, relative to |set|", V.INTRA_TURN, v, U.ONE, uu,
                     label=f"{p}.instability_rel",
                     note=None if uu is not None else "U not stated in result.json.")
        for key, title, ref in (("floor_rel", "FOG noise floor", V.FOG_FLOOR),
                                ("corrected_rel", "floor-corrected", V.INTRA_TURN_CORRECTED)):
            if num(a.get(key)) is not None:
                quantity(lst, None, title, ref, num(a[key]) or 0.0, U.ONE, label=f"{p}.{key}")


def _systematic(data: etree._Element, rid: str, path: str, s: Any) -> None:
    if not isinstance(s, Mapping):
        return
    for j, h in enumerate(s.get("harmonics") or []):
        if not isinstance(h, Mapping) or num(h.get("order")) is None:
            continue
        order = int(num(h["order"]) or 0)
        hid = ident(rid, "h", order)
        lst = el(data, "list", id=hid, ref_type=V.HARMONIC)
        name(lst, f"systematic intra-turn component, harmonic {order}: "
                  "w_set * a cos(h phi + p) (docs/method.md A4)")
        if h.get("detected") is False:
            text_el(lst, "description", "not significant: the amplitude is consistent with "
                    "zero and its phase is meaningless")
        p = f"{path}.systematic.harmonics[{j}]"
        quantity(lst, None, "order h", V.HARMONIC_ORDER, order, U.ONE, label=f"{p}.order")
        for key, u_key, title, ref, unit in (
                ("amplitude_rel", "amplitude_u_rel", "amplitude a, relative to |set|",
                 V.AMPLITUDE, U.ONE),
                ("phase_deg", "phase_u_deg", "phase p", V.PHASE, U.DEG)):
            v = num(h.get(key))
            if v is not None:
                uu = num(h.get(u_key))
                quantity(lst, ident(hid, key), title, ref, v, unit, uu, label=f"{p}.{key}",
                         note=None if uu is not None else "U not stated in result.json.")
    m = s.get("mains")
    if isinstance(m, Mapping) and num(m.get("amplitude_dps")) is not None:
        mid = ident(rid, "mains")
        lst = el(data, "list", id=mid, ref_type=V.MAINS)
        name(lst, "mains-frequency ripple, one tone fitted in time (docs/method.md A4)")
        if m.get("detected") is False:
            text_el(lst, "description", "not significant")
        p = f"{path}.systematic.mains"
        for key, u_key, title, ref, unit in (
                ("frequency_hz", None, "frequency", V.FREQUENCY, U.HERTZ),
                ("amplitude_dps", "amplitude_u_dps", "amplitude", V.AMPLITUDE, U.DEG_PER_S),
                ("phase_deg", "phase_u_deg", "phase", V.PHASE, U.DEG)):
            v = num(m.get(key))
            if v is not None:
                uu = num(m.get(u_key)) if u_key else None
                quantity(lst, ident(mid, key), title, ref, v, unit, uu, label=f"{p}.{key}",
                         note=None if uu is not None or u_key is None
                         else "U not stated in result.json.")


def _pair_result(res: etree._Element, axis: str, i: int, p: Mapping[str, Any]) -> None:
    rate = num(p.get("rate_dps"))
    pid = ident("pair", axis, f"{rate:g}" if rate is not None else i)
    path = f"axes.{axis}.pairs[{i}]"
    result = el(res, "result", id=pid, ref_type=V.PAIR)
    name(result, f"Axis {axis}, cross-calibration of the FOG at +/-{rate:g} deg/s (docs/method.md "
                 "A3 eqs. 5-6)" if rate is not None else f"Axis {axis}, pair {i + 1}")
    if p.get("method"):
        text_el(result, "description", f"method {p.get('method')}"
                + (f"; bias drift {p.get('drift_source')}" if p.get("drift_source") else ""))
    data = el(result, "data")
    for key, u_key, title, ref, unit in (
            ("rate_dps", None, "pair rate magnitude", V.NOMINAL, U.DEG_PER_S),
            ("k", "k_u", "FOG scale k (eq. 5)", f"{V.MEASURED} {V.FOG_SCALE}", U.ONE),
            ("w0_dps", "w0_u_dps", "FOG bias w0 (eq. 6)", f"{V.MEASURED} {V.FOG_BIAS}",
             U.DEG_PER_S),
            ("drift_dps_per_h", "drift_u_dps_per_h", "FOG bias drift during the pair, deg/s "
             "per hour", f"{V.MEASURED} {V.FOG_BIAS_DRIFT}", r"\degree\second\tothe{-1}"
             r"\hour\tothe{-1}")):
        v = num(p.get(key))
        if v is None:
            continue
        uu = num(p.get(u_key)) if u_key else None
        quantity(data, ident(pid, key), title, ref, v, unit, uu, label=f"{path}.{key}",
                 note=None if uu is not None or u_key is None else
                 "U not stated in result.json.")


# -- drift pulse ---------------------------------------------------------------------------

def _drift(results: etree._Element, src: Sources, checks: _Checks) -> None:
    drift = src.get("drift", {}) or {}
    mr = el(results, "measurementResult", id="platform", ref_id="item")
    name(mr, "Gyro platform: own and apparent drift per axis, azimuth (docs/method.md B)")
    lat = num(drift.get("latitude_deg"))
    if lat is not None:
        conds = el(mr, "influenceConditions")
        c = el(conds, "influenceCondition", id="siteLatitude", ref_type=V.LATITUDE)
        name(c, "Site latitude")
        quantity(el(c, "data"), None, "latitude", V.LATITUDE, lat, U.DEG,
                 label="drift.latitude_deg")
    res = el(mr, "results")
    for axis, d in (drift.get("axes", {}) or {}).items():
        if not isinstance(d, Mapping):
            continue
        path = f"drift.axes.{axis}"
        aid = ident("drift", axis)
        r = el(res, "result", id=aid, ref_type=V.MEASURED)
        name(r, f"Axis {axis}: drift, deg/h")
        data = el(r, "data")
        for key, u_key, title, ref, check in (
                ("own_dph", "own_u_dph", "own drift (w_0 + w_180) / 2",
                 f"{V.MEASURED} {V.OWN_DRIFT}", "own_drift"),
                ("apparent_dph", "apparent_u_dph", "apparent drift at position 0, "
                 "(w_0 - w_180) / 2", f"{V.MEASURED} {V.APPARENT_DRIFT}", "apparent_drift"),
                ("own_nominal_edges_dph", None, "own drift with the pulse edges at the "
                 "nominal sample times (the paper's integrator; for comparison)", V.OWN_DRIFT,
                 None)):
            v = num(d.get(key))
            if v is None:
                continue
            uu = num(d.get(u_key)) if u_key else None
            node = quantity(data, ident(aid, key), title, ref, v, U.DEG_PER_H, uu,
                            label=f"{path}.{key}", note=None if uu is not None or not u_key
                            else "U not stated in result.json.")
            if check:
                _conformity(node, checks.take(axis, None, check), U.DEG_PER_H)
        budget = d.get("budget") if isinstance(d.get("budget"), Mapping) else {}
        for key, what in (("own_u_dph", "own"), ("apparent_u_dph", "apparent")):
            terms = budget.get(key)
            if isinstance(terms, Mapping):
                _budget(data, ident(aid, "budget", what), f"uncertainty budget of the {what} "
                        "drift: standard uncertainties (k = 1) per source; U = 2 sqrt(sum "
                        "u^2) (docs/method.md B)", terms, f"{path}.budget.{key}",
                        tuple((str(k), str(k).replace("_", " ")) for k in terms), U.DEG_PER_H)
        for j, pos in enumerate(d.get("positions") or []):
            if not isinstance(pos, Mapping):
                continue
            table = num(pos.get("table_deg", pos.get("position_deg"))) or 0.0
            pp = f"{path}.positions[{j}]"
            lst = el(data, "list", id=ident(aid, "pos", f"{table:g}"), ref_type=V.DRIFT_POSITION)
            name(lst, f"platform turned to {table:g} deg: drift per cycle and mean")
            quantity(lst, None, "platform position", V.TABLE_POSITION, table, U.DEG,
                     label=f"{pp}.table_deg")
            mean = num(pos.get("mean_dph"))
            if mean is not None:
                uu = num(pos.get("u_dph"))
                quantity(lst, ident(aid, "pos", f"{table:g}", "mean_dph"), "mean drift",
                         V.MEASURED, mean, U.DEG_PER_H, uu, label=f"{pp}.mean_dph",
                         note=None if uu is not None else "U not stated in result.json.")
            if num(pos.get("std_dph")) is not None:
                quantity(lst, None, "standard deviation of the cycles", V.STD,
                         num(pos["std_dph"]) or 0.0, U.DEG_PER_H, label=f"{pp}.std_dph")
            w = [v for v in (num(x) for x in pos.get("drifts_dph") or []) if v is not None]
            if w:
                list_quantity(lst, ident(aid, "pos", f"{table:g}", "drifts_dph"),
                              "drift of each cycle, in order", V.DRIFT_CYCLES, w,
                              U.DEG_PER_H, note="Single-cycle values; their scatter (the "
                              "standard deviation above) is their uncertainty.")
    if num(drift.get("azimuth_deg")) is not None or num(drift.get("earth_horizontal_dph")) \
            is not None:
        r = el(res, "result", id="azimuth", ref_type=V.MEASURED)
        name(r, "Platform azimuth and horizontal Earth rate from the apparent drifts")
        data = el(r, "data")
        for key, u_key, title, ref, unit, check in (
                ("azimuth_deg", "azimuth_u_deg", "platform azimuth of the X input axis, "
                 "A = atan2(-app_y, app_x)", f"{V.MEASURED} {V.AZIMUTH}", U.DEG, "azimuth"),
                ("earth_horizontal_dph", "earth_horizontal_u_dph", "horizontal Earth rate "
                 "from the apparent drifts", f"{V.MEASURED} {V.EARTH_RATE}", U.DEG_PER_H,
                 "earth_horizontal_rate"),
                ("earth_horizontal_expected_dph", None, "expected 15.041 deg/h x cos(latitude)",
                 f"{V.REFERENCE} {V.EARTH_RATE}", U.DEG_PER_H, None)):
            v = num(drift.get(key))
            if v is None:
                continue
            uu = num(drift.get(u_key)) if u_key else None
            node = quantity(data, ident("drift", key), title, ref, v, unit, uu,
                            label=f"drift.{key}", note=None if uu is not None or not u_key
                            else "U not stated in result.json.")
            if check:
                _conformity(node, checks.take(None, None, check), unit)
    if not len(res):
        r = el(res, "result")
        name(r, "No drift results")
        text_el(el(r, "data"), "text", "Nothing was measured to completion.")


__all__ = ["DccInputs", "build_dcc", "si_real"]
