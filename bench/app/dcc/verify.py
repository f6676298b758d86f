"""`bench verify FILE`: is this DCC valid, intact, and does it say what result.json says?

Three checks, each printed with its outcome:
1. schema: valid against the shipped DCC 3.3.0 / D-SI 2.2.1 schemas, D-SI units parsed;
2. signature (when the file is signed): the XAdES signature verifies, so not one byte of
   the signed content changed; the values of step 3 are read from the signed content only;
3. values: every quantity (each identified by its id) and every conformity statement
   equals what result.json gives, exactly (numbers are written unrounded). The expected
   set is built from result.json by the writer, so a quantity missing, added or changed
   in the file is reported by its id.
"""

from __future__ import annotations

import base64
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from lxml import etree

from bench.app.dcc.validate import NS, validate_dcc
from bench.core import rundir_layout as layout

if TYPE_CHECKING:
    from bench.app.certificate.register import Issue
    from bench.report.certificate.sources import Sources

Values = dict[str, tuple[tuple[float, ...], tuple[float, ...] | None, str]]


def _floats(text: str | None) -> tuple[float, ...]:
    return tuple(float(x) for x in (text or "").split())


def read_quantities(root: etree._Element) -> Values:
    """id -> (values, expanded U or None, unit) of every identified dcc:quantity."""
    out: Values = {}
    for q in root.iterfind(".//dcc:quantity[@id]", NS):
        real = q.find("si:real", NS)
        if real is not None:
            u = real.find("si:measurementUncertaintyUnivariate/si:expandedMU/"
                          "si:valueExpandedMU", NS)
            out[q.get("id", "")] = (_floats(real.findtext("si:value", None, NS)),
                                    None if u is None else _floats(u.text),
                                    real.findtext("si:unit", "", NS))
            continue
        lst = q.find("si:realListXMLList", NS)
        if lst is not None:
            u = lst.find("si:measurementUncertaintyUnivariateXMLList/si:expandedMUXMLList/"
                         "si:valueExpandedMUXMLList", NS)
            out[q.get("id", "")] = (_floats(lst.findtext("si:valueXMLList", None, NS)),
                                    None if u is None else _floats(u.text),
                                    lst.findtext("si:unitXMLList", "", NS))
    return out


def read_conformity(root: etree._Element) -> dict[str, str]:
    found = {m.get("id", ""): m.findtext("dcc:conformity", "", NS)
             for m in root.iterfind(".//dcc:metaData[@id]", NS)}
    found.update({s.get("id", ""): s.findtext("dcc:conformity", "", NS)
                  for s in root.iterfind(".//dcc:statement[@id]", NS)})
    return found


@dataclass
class Report:
    lines: list[str] = field(default_factory=list)
    failed: bool = False

    def ok(self, text: str) -> None:
        self.lines.append(f"ok    {text}")

    def bad(self, text: str) -> None:
        self.lines.append(f"FAIL  {text}")
        self.failed = True

    def note(self, text: str) -> None:
        self.lines.append(f"      {text}")


def _issue_of(root: etree._Element, run_path: Path | None) -> Issue | None:
    """The issue the file claims to be, as the run's register records it; None for a
    draft (which the writer rebuilds as the run's next revision) or an unknown number."""
    from bench.app.certificate import register

    if root.find(".//dcc:statement[@id='draftStatus']", NS) is not None:
        return None
    number = root.findtext("dcc:administrativeData/dcc:coreData/dcc:uniqueIdentifier",
                           None, NS)
    return next((i for i in register.issues(run_path) if i.number == number), None)


def compare_values(root: etree._Element, src: Sources, report: Report) -> None:
    """Every quantity and conformity in `root` against the DCC result.json would give (the
    run directory's register supplies the certificate's issue number)."""
    from bench.app.dcc.writer import DccInputs, build_dcc

    issue = _issue_of(root, src.run_path)
    expected_root = build_dcc(DccInputs(src, embed_pdf=False, issue=issue)).getroot()
    want, got = read_quantities(expected_root), read_quantities(root)
    problems = [f"{k}: missing from the file" for k in want if k not in got]
    problems += [f"{k}: not in result.json" for k in got if k not in want]
    for k in want.keys() & got.keys():
        (wv, wu, wunit), (gv, gu, gunit) = want[k], got[k]
        if wv != gv:
            problems.append(f"{k}: value {gv} in the file, {wv} in result.json")
        if wu != gu:
            problems.append(f"{k}: U {gu} in the file, {wu} in result.json")
        if wunit != gunit:
            problems.append(f"{k}: unit {gunit} in the file, {wunit} expected")
    wc, gc = read_conformity(expected_root), read_conformity(root)
    problems += [f"{k}: conformity {gc.get(k)!r} in the file, {v!r} in result.json"
                 for k, v in wc.items() if gc.get(k) != v]
    w_id = expected_root.findtext("dcc:administrativeData/dcc:coreData/dcc:uniqueIdentifier",
                                  None, NS)
    g_id = root.findtext("dcc:administrativeData/dcc:coreData/dcc:uniqueIdentifier", None, NS)
    if w_id != g_id:
        problems.append(f"certificate number {g_id} in the file, {w_id} from result.json")
    if problems:
        report.bad(f"values: {len(problems)} difference(s) from result.json")
        for p in problems[:30]:
            report.note(p)
        if len(problems) > 30:
            report.note(f"... and {len(problems) - 30} more")
    else:
        report.ok(f"values: all {len(want)} quantities (value, U, unit) and {len(wc)} "
                  "conformity statements equal result.json")


def verify_file(path: Path, result_path: Path | None = None, cert: Path | None = None,
                ca: Path | None = None, need_result: bool = True,
                require_signed: bool = False) -> Report:
    """`require_signed`: the lab signs its DCCs (bench.core.lab.Lab.require_signed_dcc), so an
    unsigned file, a draft included, is not one of its certificates."""
    report = Report()
    data = path.read_bytes()
    try:
        root = etree.fromstring(data, etree.XMLParser(no_network=True, resolve_entities=False,
                                                      huge_tree=True))
    except etree.XMLSyntaxError as e:
        report.bad(f"{path}: not XML: {e}")
        return report
    v = validate_dcc(root)
    if v.valid:
        report.ok("schema: valid against DCC 3.3.0 / D-SI 2.2.1 (offline); D-SI units parsed")
    else:
        report.bad(f"schema: {len(v.lines())} problem(s)")
        for line in v.lines()[:10]:
            report.note(line)
    content = root
    if root.find("ds:Signature", NS) is not None:
        from bench.app.dcc.signing import verify_signature

        try:
            trusted = cert.read_bytes() if cert is not None else None
            check = verify_signature(data, trusted, ca)
        except Exception as e:  # noqa: BLE001 - signxml raises several kinds; all mean "no"
            report.bad(f"signature: does NOT verify: {type(e).__name__}: {e}")
            content = None
        else:
            report.ok(f"signature: XAdES verifies; signer {check.subject}; {check.trust}")
            content = check.signed_root
    elif require_signed:
        report.bad("signature: the file is not signed, and the laboratory signs its DCCs "
                   "(lab settings: signing / require_signed_dcc)" +
                   ("; it is a DRAFT, NOT AUTHORISED (bench authorise issues it)"
                    if root.find(".//dcc:statement[@id='draftStatus']", NS) is not None
                    else ""))
    else:
        report.note("signature: the file is not signed")
    result_path = result_path or path.parent / layout.RESULT
    if content is None:
        report.note("values: not compared (the signed content cannot be trusted)")
    elif result_path.is_file():
        from bench.report.certificate.sources import Sources  # decoded as the writer reads it

        compare_values(content, Sources.read(result_path), report)
        _compare_pdf(content, path.parent, report)
    elif need_result:
        report.bad(f"values: no result.json at {result_path} (give --result, or "
                   "--no-result to check schema and signature only)")
    else:
        report.note("values: not compared (--no-result)")
    return report


def _compare_pdf(root: etree._Element, run_dir: Path, report: Report) -> None:
    pdf = run_dir / layout.CERTIFICATE_PDF
    doc = root.find("dcc:document", NS)
    if doc is None or not pdf.is_file():
        return
    embedded = base64.b64decode("".join((doc.findtext("dcc:dataBase64", "", NS)).split()))
    if embedded == pdf.read_bytes():
        report.ok("document: the embedded PDF is certificate.pdf byte for byte")
    else:
        report.bad("document: the embedded PDF differs from certificate.pdf beside the file")
