"""Draft, authorise, re-issue (issue 23): what a quality manager checks before signing.

The walk itself (draft, a refused non-signatory, R1, a refused re-issue without reason,
a re-analysed draft, R2) is tests/test_document_control.py's one issue/re-issue walk, on
a copy of the session's demo run: every step renders a certificate, so the suite walks
it once. This module keeps the fixtures and readers that walk uses (PDFs read back with
pypdfium2, an independent reader; DCCs with lxml) and the "what changed" statements.
"""

from __future__ import annotations

import hashlib
import json
import re
import shutil
from pathlib import Path
from typing import Any

import pypdfium2 as pdfium
import pytest
from lxml import etree

from bench.app.certificate import authorise as auth
from bench.app.certificate import register
from bench.app.dcc.settings import ENV_LAB
from bench.core.lab import load_lab
from bench.report.certificate.parts import text_of
from tests.conftest import DemoRun
from tests.conftest import cli as _cli
from tests.registers import ISSUER, lab_file, password, sqlite_register
from tests.registers import authorise as reg_authorise
from tests.test_dcc import _lab_file, _throwaway_key

NS = {"dcc": "https://ptb.de/dcc", "ds": "http://www.w3.org/2000/09/xmldsig#"}
DRAFT = "DRAFT, NOT AUTHORISED"


@pytest.fixture(autouse=True)
def _no_lab_of_the_developer(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(ENV_LAB, raising=False)


@pytest.fixture
def lab(tmp_path: Path) -> Path:
    """A lab file naming a fresh SQLite register with the lab's accounts (tests/registers.py)."""
    return lab_file(tmp_path / "lab", sqlite_register(tmp_path / "lab"))


@pytest.fixture
def run(demo_run: DemoRun, tmp_path: Path) -> Path:
    """A copy of the session's demo run directory (conftest's `demo_run`)."""
    assert demo_run.status == 0, demo_run.stderr[-3000:]
    copy = tmp_path / demo_run.dir.name
    shutil.copytree(demo_run.dir, copy)
    return copy


def _pages(pdf: Path) -> list[str]:
    doc = pdfium.PdfDocument(str(pdf))
    try:
        return [" ".join(page.get_textpage().get_text_range().split()) for page in doc]
    finally:
        doc.close()


def _tree(path: Path) -> etree._Element:
    return etree.parse(str(path), etree.XMLParser(huge_tree=True)).getroot()


def _main_signers(root: etree._Element) -> list[str]:
    return [rp.findtext("dcc:person/dcc:name/dcc:content", None, NS)
            for rp in root.iterfind(".//dcc:respPerson", NS)
            if rp.findtext("dcc:mainSigner", None, NS) == "true"]


def _bytes(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def test_changes_are_stated_as_facts() -> None:
    old = b'{"verdict": "pass", "axes": {"outer": {"rates": [{"rate_error_rel": 1e-7}]}}}'
    new = b'{"verdict": "pass", "axes": {"outer": {"rates": [{"rate_error_rel": 2e-7}]}}}'
    assert auth.changes_between(old, new) == (
        "axes.outer.rates[0].rate_error_rel: 1e-07 -> 2e-07",)
    assert auth.changes_between(old, old)[0].startswith("results unchanged")


def test_signed_issue_and_unsigned_draft_under_a_lab_that_signs(
        run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    key, cert = _throwaway_key(tmp_path / "keys", "Test Rate Lab DCC signing")
    lab = _lab_file(tmp_path, key, cert)
    url = sqlite_register(tmp_path / "register")
    with lab.open("a") as f:
        f.write(f"register: {url}\n")
    monkeypatch.setenv("TEST_DCC_KEY_PASSWORD", "s3cret")
    # the draft is not signed: a lab that signs its DCCs does not accept it
    done = _cli("verify", str(run / "certificate.dcc.xml"), "--lab", str(lab))
    assert done.returncode == 1
    assert "FAIL  signature: the file is not signed, and the laboratory signs" in done.stdout
    assert "DRAFT" in done.stdout
    # the key the lab file names signs only once the register designates its certificate
    # (issue 42: the key is the register's decision, not a file's)
    from bench.app.register import Register
    with Register.open(url) as reg:
        assert auth.designated_signing(load_lab(lab), reg)[0].signing is None
        reg.set_setting(reg.authenticate("admin", password("admin")), auth.SIGNING_SETTING,
                        hashlib.sha256(cert.read_bytes()).hexdigest())
    # issued by a signatory of the register (the lab file's main_signer decides nothing)
    done = reg_authorise(run, "A. Tester", lab)
    assert done.returncode == 0, done.stderr
    assert "DCC signed (XAdES)" in done.stdout
    issued = run / "issued" / register.issues(run)[-1].number / "certificate.dcc.xml"
    root = _tree(issued)
    assert root.find("ds:Signature", NS) is not None
    assert _main_signers(root) == ["A. Tester"]
    done = _cli("verify", str(issued), "--lab", str(lab))
    assert done.returncode == 0, done.stdout
    assert "signer CN=Test Rate Lab DCC signing" in done.stdout


def test_a_pre_issue_check_refuses(run: Path, lab: Path) -> None:
    """The hook measurement assurance plugs into: any reason given refuses the issue."""
    seen: list[auth.IssueContext] = []

    def out_of_control(ctx: auth.IssueContext) -> list[str]:
        seen.append(ctx)
        return ["counter MY00000000 is out of statistical control and not reviewed"]

    auth.add_pre_issue_check(out_of_control)
    try:
        done = reg_authorise(run, "P. Petrov", lab)
    finally:
        auth.PRE_ISSUE_CHECKS.remove(out_of_control)
    assert done.returncode == 2
    assert "out of statistical control and not reviewed" in done.stderr
    assert seen and seen[0].signatory.name == "P. Petrov" and seen[0].simulated
    assert not (run / "issued").exists()


def test_a_real_stand_with_shared_or_missing_serials_is_not_issued(run: Path, lab: Path) -> None:
    result = json.loads((run / "result.json").read_text())
    result["stand"]["simulated"] = False                  # as if the instruments were real
    result["instruments"]["inner"]["counter"] = result["instruments"]["outer"]["counter"]
    result["instruments"]["outer"]["drive"] = "Drive maker, model X, serial 0"
    (run / "result.json").write_text(json.dumps(result))
    done = reg_authorise(run, "P. Petrov", lab)
    assert done.returncode == 2
    assert "the drive of outer reported no serial number" in done.stderr
    assert "report one serial" in done.stderr


def test_an_incomplete_run_is_not_issued(run: Path, lab: Path) -> None:
    result: dict[str, Any] = json.loads((run / "result.json").read_text())
    result["verdict"] = "incomplete"
    (run / "result.json").write_text(json.dumps(result))
    done = reg_authorise(run, "P. Petrov", lab)
    assert done.returncode == 2 and "incomplete run certifies nothing" in done.stderr


# -- the DCC states what the PDF states -------------------------------------------------

SCALES = (1.0, 100.0, 1e6, 60.0, 3600.0, 1 / 3600)    # fraction, %, ppm, arcmin, ...


def _num(text: str) -> float:
    return float(text.replace("−", "-").replace("+", ""))


def _decimals(text: str) -> int:
    return len(text.split(".")[1]) if "." in text else 0


def _dcc_values(root: etree._Element) -> list[tuple[float, float | None]]:
    """Every (value, U) of the DCC, unrounded, from si:real and si:realListXMLList."""
    si = {"si": "https://ptb.de/si"}
    out: list[tuple[float, float | None]] = []
    for real in root.iterfind(".//si:real", si):
        u = real.findtext("si:measurementUncertaintyUnivariate/si:expandedMU/"
                          "si:valueExpandedMU", None, si)
        out.append((float(real.findtext("si:value", None, si)), float(u) if u else None))
    for lst in root.iterfind(".//si:realListXMLList", si):
        vs = [float(x) for x in lst.findtext("si:valueXMLList", "", si).split()]
        us = lst.findtext("si:measurementUncertaintyUnivariateXMLList/si:expandedMUXMLList/"
                          "si:valueExpandedMUXMLList", None, si)
        out += list(zip(vs, [float(x) for x in us.split()] if us else [None] * len(vs),
                        strict=True))
    return out


def _figures_missing(pdf_text: str, root: etree._Element, rates: set[float]
                     ) -> tuple[list[str], list[str], int]:
    """Each 'v ± U' of the PDF must be a DCC value and U that print so (at the PDF's
    decimals, in one of the PDF's units; a figure per °/s of the set rate or per % of it
    is the DCC's relative value times or over the set rate); each '< L' a DCC value (or
    value + U) that prints as L."""
    values = _dcc_values(root)
    scales = [s * f for s in SCALES for f in (1.0, *rates, *(1 / r for r in rates))]
    pairs = re.findall(r"([−+]?\d[\d.]*)\s*±\s*(\d[\d.]*)", pdf_text)
    limits = re.findall(r"<\s*(\d[\d.]*)", pdf_text)

    def near(x: float, y: float, d: int) -> bool:
        return abs(x - y) <= 0.5 * 10 ** -d * 1.0001 + 1e-15

    bad_pairs = [f"{v} ± {u}" for v, u in pairs
                 if not any(uu is not None and near(val * s, _num(v), _decimals(u))
                            and abs(uu * s - _num(u)) <= 10 ** -_decimals(u) * 1.0001
                            for val, uu in values for s in scales)]
    bad_limits = [f"< {x}" for x in limits
                  if not any(near(val * s, _num(x), _decimals(x))
                             or (uu is not None and near((val + uu) * s, _num(x), _decimals(x)))
                             for val, uu in values for s in scales)]
    return bad_pairs, bad_limits, len(pairs) + len(limits)


@pytest.mark.parametrize("which", ["demo", "drift"])
def test_the_dcc_states_what_the_pdf_states(which: str, request: pytest.FixtureRequest,
                                            tmp_path: Path, lab: Path) -> None:
    done: DemoRun = request.getfixturevalue({"demo": "demo_run", "drift": "drift_demo_run"}[which])
    assert done.status == 0, done.stderr[-3000:]
    run = tmp_path / "run"
    shutil.copytree(done.dir, run)
    assert reg_authorise(run, "P. Petrov", lab).returncode == 0
    issued = run / "issued" / register.issues(run)[-1].number
    pages = _pages(issued / "certificate.pdf")
    text = "\n".join(pages)
    root = _tree(issued / "certificate.dcc.xml")
    result = json.loads((run / "result.json").read_text())
    # the figures, line by line (a nominal condition is the procedure file's text, in the
    # DCC too)
    doc = pdfium.PdfDocument(str(issued / "certificate.pdf"))
    raw = "\n".join(page.get_textpage().get_text_range() for page in doc)
    doc.close()
    figures = re.sub(r"\(nominal,\s+not measured\)[^\n]*", "", raw)
    # the conditions table prints each nominal value as the procedure states it
    for value in (result.get("conditions") or {}).values():
        figures = figures.replace(text_of(value), "")
    rates = {abs(r["set_rate_dps"]) for a in (result.get("axes") or {}).values()
             for r in a.get("rates", [])}
    bad_pairs, bad_limits, n = _figures_missing(figures, root, rates)
    # drift: the position means are budget inputs, stated with u and nu, no U (issue 43)
    assert n > (100 if which == "demo" else 8)
    assert not bad_pairs, bad_pairs
    assert not bad_limits, bad_limits
    # the same people, laboratory, addresses and customer; the issuer as the lab register
    # holds it (issue 54), not as the procedure file names it
    adm = root.find("dcc:administrativeData", NS)
    cert = {**result["certificate"], "laboratory": ISSUER["issuer.name"],
            "address": ISSUER["issuer.address"]}
    c = "dcc:name/dcc:content"
    assert adm.findtext(f"dcc:calibrationLaboratory/dcc:contact/{c}", None, NS) \
        == cert["laboratory"]
    assert result["certificate"]["laboratory"] not in text
    assert cert["laboratory"] in text and cert["address"] in " ".join(text.split())
    assert cert["address"] in [x.text for x in adm.iterfind(
        "dcc:calibrationLaboratory/dcc:contact/dcc:location/dcc:further/dcc:content", NS)]
    assert adm.findtext(f"dcc:customer/{c}", None, NS) == cert["customer"]
    further = [x.text for x in adm.iterfind("dcc:customer/dcc:location/dcc:further/"
                                            "dcc:content", NS)]
    assert cert["customer_address"] in further
    assert f"Contact: {cert['customer_contact']}" in further
    for s in (cert["customer"], cert["customer_address"], cert["customer_contact"]):
        assert s in " ".join(text.split())
    people = {rp.findtext(f"dcc:person/{c}", None, NS)
              for rp in adm.iterfind("dcc:respPersons/dcc:respPerson", NS)}
    # the performer no account authenticated is "not recorded" in both (issue 42: never a
    # name from the procedure file), and the signatory the register authenticated
    assert people == {"not recorded", "P. Petrov"}
    for name in people:
        assert name in text
    assert "A. Ivanova" not in text         # the procedure file's "performer"
    assert _main_signers(root) == ["P. Petrov"]
    assert "SIMULATED" in adm.findtext(".//dcc:item/dcc:description/dcc:content", "", NS)
