"""Document control after an issue (issue 43): an issued revision's files are never
rewritten, and what `bench dcc` / `bench analyze` write afterwards is a draft with a draft
identifier, never an issued number; `bench verify --register` states each file's status.

The walk: issue R1 through the lab register, re-issue R2, then `bench dcc RUN_DIR` and
`bench analyze RUN_DIR` on the same run directory (the demo run, copied).
"""

from __future__ import annotations

import base64
import json
import shutil
from pathlib import Path
from typing import Any

import pytest
from lxml import etree

from bench.app.certificate import authorise as auth
from bench.app.certificate import register
from bench.app.records.extract import record_of
from bench.app.records.store import Records
from bench.app.register import Register
from tests import test_authorise
from tests.conftest import DemoRun, cli
from tests.registers import authorise

NS = test_authorise.NS

run = test_authorise.run        # a copy of the demo run
lab = test_authorise.lab        # a lab file naming a fresh SQLite register
_pages = test_authorise._pages
_main_signers = test_authorise._main_signers
_bytes = test_authorise._bytes
DRAFT = test_authorise.DRAFT


def _url(lab: Path) -> str:
    return next(line.split(": ", 1)[1] for line in lab.read_text().splitlines()
                if line.startswith("register:"))


def _tree(path: Path) -> etree._Element:
    return etree.parse(str(path), etree.XMLParser(huge_tree=True)).getroot()


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _assert_draft(run: Path, numbers: list[str]) -> None:
    """The run directory's certificate.* are one draft: a draft identifier, no issue date,
    no issued number as its own, and the DCC embeds the draft PDF beside it."""
    root = _tree(run / "certificate.dcc.xml")
    core = root.find("dcc:administrativeData/dcc:coreData", NS)
    own = core.findtext("dcc:uniqueIdentifier", "", NS)
    assert own.startswith("DRAFT-") and own not in numbers
    assert core.find("dcc:issueDate", NS) is None          # the PDF says "none"
    assert core.find("dcc:reportAmendedSubstituted", NS) is None
    assert root.find(".//dcc:statement[@id='draftStatus']", NS) is not None
    pdf = (run / "certificate.pdf").read_bytes()
    embedded = base64.b64decode(root.findtext("dcc:document/dcc:dataBase64", "", NS))
    assert embedded == pdf
    for number in numbers:
        assert pdf != (run / "issued" / number / "certificate.pdf").read_bytes()
    pages = _pages(run / "certificate.pdf")
    assert all("DRAFT, NOT AUTHORISED" in p for p in pages)
    head = pages[0].split("Revision")[0]
    assert own in pages[0]
    assert not any(number in head for number in numbers)
    assert "Date of issue (authorisation) none: DRAFT, NOT AUTHORISED" in " ".join(pages)


def _status(path: Path, url: str) -> str:
    done = cli("verify", str(path), "--register", url)
    return next(line for line in done.stdout.splitlines() if line.startswith("register "))


@pytest.mark.timeout(600)   # two issues, `bench dcc`, `bench analyze`: minutes when loaded
def test_issue_reissue_then_dcc_and_analyze_write_only_drafts(run: Path, lab: Path) -> None:
    """The one walk (issue 23's draft/authorise/re-issue checks, then issue 43's document
    control): each step costs a certificate rendering, so the suite walks it once."""
    url = _url(lab)
    # the draft: marked on every page, no date of issue, no authorisation claimed
    pages = _pages(run / "certificate.pdf")
    assert len(pages) > 3
    assert all(DRAFT in p for p in pages)
    text = " ".join(pages)
    assert "Date of issue:" not in text and "authorised for issue by" not in text
    assert "Date of issue (authorisation) none: DRAFT, NOT AUTHORISED" in text
    draft_dcc = _tree(run / "certificate.dcc.xml")
    assert draft_dcc.find(".//dcc:statement[@id='draftStatus']", NS) is not None
    assert _main_signers(draft_dcc) == []
    assert not (run / register.REGISTER_NAME).exists()

    # an account without the signatory role (she performs calibrations): refused, nothing
    # kept, though the procedure file lists her among its signatories
    done = authorise(run, "A. Ivanova", lab)
    assert done.returncode == 2, done.stdout
    assert "'A. Ivanova' does not hold the signatory role" in done.stderr
    assert not (run / register.REGISTER_NAME).exists() and not (run / "issued").exists()

    # the issue: names the authoriser in the PDF and as the DCC's main signer
    done = authorise(run, "P. Petrov", lab)
    assert done.returncode == 0, done.stderr
    first = register.issues(run)
    assert [(i.revision, i.signatory) for i in first] == [(1, "P. Petrov")]
    rev1 = run / "issued" / first[0].number
    pages = _pages(rev1 / "certificate.pdf")
    assert not any("DRAFT" in p for p in pages)
    text = " ".join(pages)
    assert (f"Date of issue: {first[0].issue_date}, the date on which this certificate was "
            "authorised for issue by P. Petrov, Technical manager") in text
    dcc = _tree(rev1 / "certificate.dcc.xml")
    assert _main_signers(dcc) == ["P. Petrov"]
    assert dcc.find(".//dcc:statement[@id='draftStatus']", NS) is None
    assert dcc.findtext(".//dcc:coreData/dcc:uniqueIdentifier", None, NS) == first[0].number
    assert (run / "certificate.pdf").read_bytes() == (rev1 / "certificate.pdf").read_bytes()
    kept = _bytes(rev1)

    # a re-issue without a reason: refused
    done = authorise(run, "P. Petrov", lab)
    assert done.returncode == 2
    assert "must say why (--reason TEXT" in done.stderr
    assert len(register.issues(run)) == 1

    # re-analysed: a new draft of revision 2 (a draft identifier, never the number the
    # register allocated), revision 1 untouched; then re-issued
    assert cli("analyze", str(run), "--quiet").returncode == 0
    _assert_draft(run, [first[0].number])
    assert "-R2" in _pages(run / "certificate.pdf")[0]
    assert _bytes(rev1) == kept
    reason = "customer contact corrected on the customer's request"
    done = authorise(run, "P. Petrov", lab, "--reason", reason)
    assert done.returncode == 0, done.stderr
    second = register.issues(run)[-1]
    assert (second.revision, second.replaces, second.reason) == (2, first[0].number, reason)
    now = _bytes(rev1)
    assert {k: now[k] for k in kept} == kept                      # byte for byte
    assert set(now) - set(kept) == {auth.WITHDRAWN_NAME}
    assert "WITHDRAWN" in (rev1 / auth.WITHDRAWN_NAME).read_text()
    text = " ".join(_pages(run / "issued" / second.number / "certificate.pdf"))
    assert f"replaces certificate {first[0].number}, which is withdrawn" in text
    assert f"Reason for the re-issue: {reason}" in text
    assert "What changed: results unchanged" in text
    dcc = _tree(run / "issued" / second.number / "certificate.dcc.xml")
    assert reason in dcc.findtext(".//dcc:statement[@id='authorisation']/dcc:declaration/"
                                  "dcc:content", "", NS)

    issues = register.issues(run)
    numbers = [i.number for i in issues]
    assert [i.revision for i in issues] == [1, 2]
    issued = _snapshot(run / "issued")
    # the run directory holds R2's copies until something rewrites them
    assert (run / "certificate.pdf").read_bytes() == issued[f"{numbers[1]}/certificate.pdf"]
    # R2's DCC carries its number and date and names the one it substitutes
    ns = {"dcc": "https://ptb.de/dcc"}
    core = etree.parse(str(run / "certificate.dcc.xml")).getroot().find(
        "dcc:administrativeData/dcc:coreData", ns)
    assert core.findtext("dcc:uniqueIdentifier", "", ns) == numbers[1] != numbers[0]
    assert core.findtext("dcc:issueDate", "", ns) == issues[1].issue_date
    change = core.find("dcc:reportAmendedSubstituted", ns)
    assert change.findtext("dcc:typeOfChange", "", ns) == "substituted"
    assert change.findtext("dcc:replacedUniqueIdentifier", "", ns) == numbers[0]
    # every issued DCC verifies against the result.json it was issued with
    for issue in issues:
        done = cli("verify", str(run / "issued" / issue.number / "certificate.dcc.xml"))
        assert done.returncode == 0, done.stdout
    # the run's register file is a copy of what the register holds, and the records cite
    # the issued revision with the digests of its files as stored, never a draft's
    with Register.open(url, migrate=False) as reg:
        held = reg.revisions(issues[0].number)
    assert [(i.number, i.audit_digest) for i in issues] == [
        (r.shown_number, r.audit_digest) for r in held]
    assert issues[1].signatory == "P. Petrov" and issues[1].meaning == "authorised for issue"
    with Records.open(f"sqlite:///{run.parent / 'records.sqlite'}") as rec:
        info = rec.run(record_of(run).uid)
    assert info is not None and info.certificate_number == numbers[1]
    assert info.cert_files and all(sha == held[1].digests()[name]
                                   for name, sha in info.cert_files.items())

    # a copy of the run directory is the same run: never a second revision 1 of a number
    # (the register allocates one number per run; issue 42, finding 2)
    copy = run.parent / "copy" / run.name
    shutil.copytree(run, copy)
    done = authorise(copy, "P. Petrov", lab)
    assert done.returncode == 2 and "already issued" in done.stderr
    assert _snapshot(copy / "issued") == issued

    done = cli("dcc", str(run))
    assert done.returncode == 0, done.stderr
    assert f"was the copy of issued certificate {numbers[1]}" in done.stderr
    assert _snapshot(run / "issued") == issued             # no file added, none rewritten
    _assert_draft(run, numbers)

    assert cli("analyze", str(run), "--quiet").returncode == 0
    assert _snapshot(run / "issued") == issued
    _assert_draft(run, numbers)
    assert register.issues(run) == issues                  # a draft is recorded nowhere

    # the register's word on each file
    assert ": withdrawn: certificate " + numbers[0] in _status(
        run / "issued" / numbers[0] / "certificate.dcc.xml", url)
    assert ": issued: certificate " + numbers[1] in _status(
        run / "issued" / numbers[1] / "certificate.dcc.xml", url)
    assert ": not issued (draft)" in _status(run / "certificate.dcc.xml", url)
    assert ": not issued" in _status(run / "certificate.pdf", url)
    # and without the register, the file's own status line
    done = cli("verify", str(run / "certificate.dcc.xml"))
    assert done.returncode == 0, done.stdout
    assert "status: not issued (draft)" in done.stdout
    done = cli("verify", str(run / "issued" / numbers[0] / "certificate.dcc.xml"))
    assert f"status: withdrawn (replaced by {numbers[1]})" in done.stdout
    done = cli("verify", str(run / "issued" / numbers[1] / "certificate.dcc.xml"))
    assert "status: issued (revision 2" in done.stdout


# -- the DCC's equipment list is the PDF's traceability table ------------------------------

def _cells(row: Any) -> list[str]:
    return [" ".join(c.text_content().split()) for c in row]


def _traceability_rows(html_file: Path) -> list[list[str]]:
    """The traceability table's rows as the certificate prints them (the HTML carries the
    PDF's content, from the same document)."""
    from lxml import html as lxml_html

    table = next(t for t in lxml_html.fromstring(html_file.read_text(encoding="utf-8"))
                 .iter("table") if "Serial (read back)" in t.text_content())
    return [_cells(r) for r in table.iter("tr") if len(r) > 1 and r[0].tag == "td"]


def _content(me: etree._Element, ref_type: str) -> str | None:
    return me.findtext(f"dcc:description/dcc:content[@refType='{ref_type}']", None, NS)


def _identification(me: etree._Element, ref_type: str) -> str | None:
    return me.findtext(f"dcc:identifications/dcc:identification[@refType='{ref_type}']"
                       "/dcc:value", None, NS)


@pytest.mark.parametrize("which", ["demo", "drift"])
def test_every_row_of_the_traceability_table_is_in_the_dcc(
        which: str, request: pytest.FixtureRequest) -> None:
    done: DemoRun = request.getfixturevalue({"demo": "demo_run",
                                             "drift": "drift_demo_run"}[which])
    assert done.status == 0, done.stderr[-3000:]
    rows = _traceability_rows(done.dir / "certificate.html")
    dcc = _tree(done.dir / "certificate.dcc.xml")
    found = dcc.findall(".//dcc:measuringEquipments/dcc:measuringEquipment", NS)
    assert len(rows) == len(found) > 2
    for (item, serial, certificate, issuer, due, traces, status), me in zip(rows, found,
                                                                          strict=True):
        assert me.findtext("dcc:name/dcc:content", None, NS) == item
        assert _identification(me, "ratebench_serialNumber") == serial, item
        assert _identification(me, "ratebench_calibrationCertificate") == (
            None if certificate == "—" else certificate), item
        assert _content(me, "ratebench_calibrationIssuer") == issuer
        assert _content(me, "ratebench_calibrationDue") == due, item
        assert " ".join((_content(me, "ratebench_quantityTraced") or "").split()) == traces
        assert " ".join((_content(me, "ratebench_traceabilityStatus") or "").split()) == status
        assert "NOT REPORTED" not in serial and "as the PDF" not in etree.tostring(
            me).decode()
    items = [r[0] for r in rows]
    if which == "demo":       # the 10 MHz reference, and each counter's input read back
        gps = rows[next(i for i, t in enumerate(items) if "10 MHz reference" in t)]
        assert gps[1:5] == ["SIM-GPSDO-01 (stated, not read back)", "SIM-CAL-GPSDO-0042",
                            "Simulated Time and Frequency Lab (demo)", "2027-03-31"]
        refs = [r for r in rows if r[0].startswith("counter reference input")]
        assert len(refs) == 2
        assert all(r[6].startswith("read back from the counter: external reference at Ext "
                                   "Ref In") for r in refs)


# -- every item a value rests on has its own identity ---------------------------------------

def _deviations(doc: Any) -> str:
    from bench.report.certificate.model import Para

    section = next(s for s in doc.sections if s.title == "Deviations")
    return " ".join(b.text for b in section.blocks if isinstance(b, Para))


def _identity_statements(root: etree._Element) -> str:
    return " ".join(st.findtext("dcc:declaration/dcc:content", "", NS) for st in
                    root.iterfind(".//dcc:statement[@refType='ratebench_equipmentIdentity']",
                                  NS))


def test_shared_or_missing_identities_are_stated_on_twins(
        demo_run: DemoRun, drift_demo_run: DemoRun) -> None:
    from bench.app.certificate import build_document
    from bench.app.dcc.writer import DccInputs, build_dcc
    from bench.report.certificate.sources import Sources

    result = json.loads((demo_run.dir / "result.json").read_text())
    # two FOGs answering one serial (the demo's twins answer their own)
    result["instruments"]["inner"]["fog"] = result["instruments"]["outer"]["fog"]
    shared_fog = "the fog of outer, fog of inner report one serial (1760-20231)"
    sensors = ("zero-mark slot sensors (outer and inner) (traceability[1]) states one serial "
               "for several items (SIM-BS5-01/02)")
    on_twins = "A finding of a run on simulated twins: a real stand with it is not issued."
    text = _deviations(build_document(Sources.load(result, demo_run.dir)))
    assert shared_fog in text and sensors in text and on_twins in text
    dcc = _identity_statements(build_dcc(DccInputs(Sources.load(result, demo_run.dir),
                                                   embed_pdf=False)).getroot())
    assert shared_fog in dcc and sensors in dcc and on_twins in dcc
    # the drift stand's k_as entry names no serial (one certificate for two sensors): the
    # files the drift demo wrote say so
    no_serial = ("command angle sensors' scale k_as (x and y) (traceability[0]) states no "
                 "serial number")
    assert no_serial in _identity_statements(_tree(drift_demo_run.dir / "certificate.dcc.xml"))
    pdf = " ".join(_pages(drift_demo_run.dir / "certificate.pdf"))
    assert "k_as (x and y)" in pdf and "(traceability[0]) states no serial number" in pdf


def test_a_real_stand_whose_items_share_or_lack_a_serial_is_refused(run: Path,
                                                                    lab: Path) -> None:
    result = json.loads((run / "result.json").read_text())
    result["stand"]["simulated"] = False                  # as if the instruments were real
    result["instruments"]["inner"]["fog"] = result["instruments"]["outer"]["fog"]
    (run / "result.json").write_text(json.dumps(result))
    stand = run / "stand.yaml"                            # the 10 MHz reference: no serial
    stand.write_text(stand.read_text().replace(" serial: SIM-GPSDO-01,", ""))
    done = authorise(run, "P. Petrov", lab)
    assert done.returncode == 2, done.stdout
    err = " ".join(done.stderr.split())
    assert "the fog of outer, fog of inner report one serial (1760-20231)" in err
    assert "(traceability[1]) states one serial for several items (SIM-BS5-01/02)" in err
    assert "(traceability[0]) states no serial number" in err
    assert not (run / "issued").exists()


# -- conditions: nominal as nominal, measured as measured, one mains frequency --------------

def test_conditions_nominal_measured_and_one_mains_frequency(demo_run: DemoRun) -> None:
    from bench.app.certificate.build import Sources
    from bench.app.certificate.conditions import NOT_MEASURED, condition_rows

    result = json.loads((demo_run.dir / "result.json").read_text())
    rows = {r.key: r for r in condition_rows(Sources.load(result, demo_run.dir))}
    assert (rows["temperature_c"].nominal, rows["temperature_c"].measured) == (
        "20 ± 2", NOT_MEASURED)                        # the room: nominal only
    assert rows["fog_temperature"].nominal == "—"      # the FOG's: measured only
    assert "°C" in rows["fog_temperature"].measured and "axis outer" in \
        rows["fog_temperature"].measured
    assert rows["note"].measured == "—"
    assert rows["mains_frequency"].nominal.startswith("50 Hz")
    # the two axes' fits find different tones: both stated as found, none as the lab's
    found = "found from the data (50 and 60 Hz tried; the larger significant tone)"
    for axis, hz in (("outer", 60.0), ("inner", 50.0)):
        for rate in result["axes"][axis]["rates"]:
            if rate.get("systematic", {}).get("mains"):
                rate["systematic"]["mains"].update(frequency_hz=hz, source=found)
    mains = next(r for r in condition_rows(Sources.load(result, demo_run.dir))
                 if r.key == "mains_frequency")
    assert mains.nominal.startswith("not stated")
    assert mains.measured.startswith("found from the data, NOT one frequency: axis outer: "
                                     "60 Hz; axis inner: 50 Hz")
    from bench.app.dcc.writer import DccInputs, build_dcc

    root = build_dcc(DccInputs(Sources.load(result, demo_run.dir), embed_pdf=False)).getroot()
    cond = root.find(".//dcc:influenceCondition[@id='cond_mains_frequency']", NS)
    assert "NOT one frequency" in cond.findtext("dcc:description/dcc:content", "", NS)
