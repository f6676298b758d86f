"""The DCC's usedMethods, usedSoftware, measuringEquipments and influenceConditions,
common to every measurementResult: the method document embedded, one entry per section
used, the procedure file, the GUM statement, the instruments, the recorded conditions.
"""

from __future__ import annotations

import base64
import re
from collections.abc import Mapping
from importlib import resources

from lxml import etree

import bench
from bench.app.certificate.build import Sources
from bench.app.certificate.conditions import NOT_MEASURED, condition_rows
from bench.app.certificate.equipment import NONE, equipment_list
from bench.core.yamlfile import YamlValue
from bench.kind import DccPart
from bench.report.dcc import units as U
from bench.report.dcc import vocab as V
from bench.report.dcc.xml import (
    DCC_NS,
    LANG,
    NOT_RECORDED,
    el,
    ident,
    name,
    num,
    quantity,
    text_el,
)
from bench.report.result_frame import FogAxisTemperature

# bench/method.md = docs/method.md; each procedure kind names the sections it follows
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


def methods_and_conditions(results: etree._Element, src: Sources, kind: DccPart) -> None:
    used = el(results, "usedMethods")
    document, sections = method_sections()
    reference, followed = kind.dcc_used_methods(src)
    m = el(used, "usedMethod", id="methodDocument", ref_type=V.METHOD)
    name(m, f"ratebench method document ({METHOD_DOC}), as shipped with this release")
    desc = text_el(m, "description", reference)
    f = el(desc, "file")
    el(f, "fileName", "method.md")
    el(f, "mimeType", "text/markdown")
    el(f, "dataBase64", base64.b64encode(document).decode("ascii"))
    for sec in followed:
        heading, text = sections.get(sec, (f"section {sec}", f"see {METHOD_DOC}"))
        m = el(used, "usedMethod", id=ident("method", sec), ref_type=V.METHOD)
        name(m, f"{METHOD_DOC} {sec}: {heading}")
        text_el(m, "description", text or f"see {METHOD_DOC}")
        el(m, "reference", f"{METHOD_DOC} section {sec} (embedded above)")
    pf = src.frame.procedure_file
    proc_name = pf.name or src.meta.get("procedure_name")
    if proc_name:
        m = el(used, "usedMethod", id="procedureFile")
        name(m, f"Procedure file {proc_name}")
        text_el(m, "description", f"The procedure as run, SHA-256 "
                f"{pf.sha256 or src.meta.get('procedure_sha256') or NOT_RECORDED}; "
                f"settings: {_settings(src)}.")
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
    cond = src.frame.conditions or src.procedure_file.get("conditions") or {}
    # the PDF's conditions table, row by row (bench/app/certificate/conditions.py)
    rows = {r.key: r for r in condition_rows(src)}
    if rows:
        conds = el(results, "influenceConditions")
        for axis, ax in src.frame.conditions_measured.fog_axes.items():
            _measured_temperature(conds, axis, ax)
        for key, value in (cond.items() if isinstance(cond, Mapping) else ()):
            row = rows.get(str(key))
            _condition(conds, str(key), value, row.measured if row else NOT_MEASURED)
        for key in ("temperature", "mains_frequency"):
            row = rows.get(key)
            if row is not None and key not in cond:
                c = el(conds, "influenceCondition", id=ident("cond", key),
                       ref_type=V.CONDITION)
                name(c, row.condition)
                text_el(c, "description", f"Nominal: {row.nominal}. Measured in this run: "
                        f"{row.measured}.")
                text_el(el(c, "data"), "text", row.measured)


def _measured_temperature(conds: etree._Element, axis: str,
                          temperatures: FogAxisTemperature) -> None:
    """The FOG's temperature over the axis's halves, as the bench measured it."""
    c = el(conds, "influenceCondition", id=ident("cond", "fog-temperature", axis),
           ref_type=V.TEMPERATURE)
    name(c, f"Temperature of the FOG on the table top, axis {axis} (measured)")
    text_el(c, "description", "Measured by the bench: the temperature field of every FOG "
            "frame (integer deg C) over all halves of the axis; the table top at the FOG, "
            "not the room. Per half: the PDF's conditions table.")
    data = el(c, "data")
    for key, title, ref, value in (
            ("min_c", "minimum", V.TEMPERATURE_MIN, temperatures.min_c),
            ("mean_c", "mean", V.TEMPERATURE, temperatures.mean_c),
            ("max_c", "maximum", V.TEMPERATURE_MAX, temperatures.max_c)):
        if value is not None:
            quantity(data, ident("cond", "fog-temperature", axis, key), title, ref,
                     float(value), U.CELSIUS)


def _settings(src: Sources) -> str:
    """The procedure's settings as result.json's `method` states them, one line (its
    tolerances are the conformity statements')."""
    return "; ".join(f"{k} = {v}" for k, v in src.frame.method.items()
                     if k != "tolerance") or NOT_RECORDED


def _content(parent: etree._Element, text: str, ref_type: str | None = None) -> None:
    el(parent, "content", text or "-", lang=LANG, ref_type=ref_type)


def _equipment(src: Sources) -> etree._Element | None:
    """The PDF's traceability table, row by row (bench/app/certificate/equipment.py
    computes the rows once for both): item, serial as printed (read back, or stated),
    calibration certificate and issuer, due date, quantity traced, status, and the
    identity the instrument reported; the table's notes (assurance status) as the list's
    description."""
    found = equipment_list(src)
    if not found.rows:
        return None
    eq = etree.Element(f"{{{DCC_NS}}}measuringEquipments")
    name(eq, "Metrological traceability: calibration of the instruments and references "
             "used (the PDF's traceability table)")
    desc = el(eq, "description")
    for note in found.notes:
        _content(desc, note)
    for row in found.rows:
        stated = row.certificate != NONE
        me = el(eq, "measuringEquipment", id=ident("eq", row.where),
                ref_type=V.NORMAL_USED if stated else None)
        name(me, row.item)
        d = el(me, "description")
        _content(d, f"Stand file key: {row.where}")
        _content(d, row.issuer, V.CALIBRATION_ISSUER)
        _content(d, row.due, V.CALIBRATION_DUE)
        _content(d, row.traces, V.QUANTITY_TRACED)
        _content(d, row.status, V.TRACEABILITY_STATUS)
        if row.identity:
            _content(d, row.identity, V.REPORTED_IDENTITY)
        ids = el(me, "identifications")
        idn = el(ids, "identification", ref_type=V.SERIAL_NUMBER)
        el(idn, "issuer", "manufacturer")
        el(idn, "value", row.serial)
        name(idn, "Serial number (read back from the instrument, or as stated)")
        if stated:
            idn = el(ids, "identification", ref_type=V.CALIBRATION_CERTIFICATE)
            el(idn, "issuer", "other")
            el(idn, "value", row.certificate)
            name(idn, f"Calibration certificate, issued by {row.issuer}")
    return eq


_NUMBER = r"[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?"
_CONDITION_UNITS = {"c": (U.CELSIUS, V.TEMPERATURE, V.TEMPERATURE_MIN, V.TEMPERATURE_MAX),
                    "pct": (U.PERCENT, V.HUMIDITY, V.HUMIDITY_MIN, V.HUMIDITY_MAX),
                    "hpa": (U.HECTOPASCAL, V.CONDITION, None, None)}


def _condition(conds: etree._Element, key: str, value: YamlValue, measured: str) -> None:
    """A stated condition: '20 +/- 2' under `temperature_c` becomes 18 ... 22 degC; text
    that is not a number with its unit stays text (it is never guessed). `measured`: what
    this run measured of it (the PDF's column), usually "not measured"."""
    suffix = key.rsplit("_", 1)[-1].lower() if "_" in key else ""
    text = str(value)
    if key.lower().startswith("humid") and text.strip().endswith("%"):
        suffix, text = "pct", text.strip()[:-1]
    spec = _CONDITION_UNITS.get(suffix)
    label = key.rsplit("_", 1)[0] if spec else key
    c = el(conds, "influenceCondition", id=ident("cond", key),
           ref_type=spec[1] if spec else V.CONDITION)
    name(c, label.replace("_", " ").capitalize())
    text_el(c, "description", f"As stated in the procedure file (nominal): {key}: "
            f"{value}. Measured in this run: {measured}.")
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
