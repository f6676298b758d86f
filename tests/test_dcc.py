"""The DCC (PTB DCC 3.3.0 XML) of real demo runs, read back without our writer.

The session's `bench run` of the demo and of the drift demo (tests/conftest.py), copied
once for this module and shared by the tests below. Values are read back with lxml and compared with
result.json by keys this file names itself; validity is checked by our validator (libxml2)
and, independently, by xmlschema on the shipped schema files, fetching nothing. The
invalid public example must be refused, and a signed file whose content was changed must
fail `bench verify`.
"""

from __future__ import annotations

import copy
import datetime as dt
import hashlib
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import xmlschema
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import NameOID
from lxml import etree

from bench.app.dcc.settings import ENV_LAB
from bench.app.dcc.validate import validate_dcc
from bench.report.dcc.units import unit_problem
from tests.conftest import CONFIGS, ROOT, DemoRun, unavailable
from tests.conftest import cli as _cli
from tests.registers import add_register, authorise, designate

SCHEMAS = ROOT / "bench" / "app" / "dcc" / "schemas"
EXAMPLES = ROOT / "tests" / "data" / "dcc"
NS = {"dcc": "https://ptb.de/dcc", "si": "https://ptb.de/si",
      "ds": "http://www.w3.org/2000/09/xmldsig#"}


@pytest.fixture(autouse=True)
def _no_lab_of_the_developer(monkeypatch: pytest.MonkeyPatch) -> None:
    """A lab settings file named in the developer's environment must not sign test runs."""
    monkeypatch.delenv(ENV_LAB, raising=False)


def _shared(done: DemoRun, dest: Path) -> dict[str, Any]:
    """The session's run of a shipped example (conftest), its runs folder copied here: the
    module rewrites its DCC in place. No rerun on a timing fault: the co-simulation clock
    leaves none to chance, so one would be a finding."""
    run_dir = done.copy_to(dest)
    return {"status": done.status, "stdout": done.stdout, "stderr": done.stderr,
            "dir": run_dir, "result": done.result}


@pytest.fixture(scope="module")
def demo(demo_run: DemoRun, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    return _shared(demo_run, tmp_path_factory.mktemp("dcc-demo") / "runs")


@pytest.fixture(scope="module")
def drift(drift_demo_run: DemoRun, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    return _shared(drift_demo_run, tmp_path_factory.mktemp("dcc-drift") / "runs")


# -- reading back, independent of bench.app.dcc ------------------------------------------------

def _second_opinion(path: Path) -> list[str]:
    """xmlschema (pure Python, not the libxml2 our validator uses) on the shipped files, its
    imports mapped by a table written here; `allow="local"` refuses any remote fetch."""
    local = {f"https://{host}/{rel}": str(SCHEMAS / rel)
             for host in ("ptb.de", "www.ptb.de")
             for rel in ("dcc/v3.3.0/dcc.xsd", "si/v2.2.1/SI_Format.xsd",
                         "si/v2.2.1/qudt/quantitykind.xsd", "dcc/d-sig/xmldsig-core-schema.xsd")}
    schema = xmlschema.XMLSchema(str(SCHEMAS / "dcc" / "v3.3.0" / "dcc.xsd"),
                                 uri_mapper=lambda uri: local.get(uri, uri), allow="local")
    return [f"{e.path}: {e.reason}" for e in schema.iter_errors(str(path))]


def _tree(path: Path) -> etree._Element:
    return etree.parse(str(path), etree.XMLParser(huge_tree=True, no_network=True)).getroot()


def _lookup(result: dict[str, Any], path: str) -> Any:
    """'axes.outer.rates[0].rate_error_rel' -> the value in result.json."""
    node: Any = result
    for part in re.findall(r"[^.\[\]]+|\[\d+\]", path):
        node = node[int(part[1:-1])] if part.startswith("[") else node[part]
    return node


def _reals(root: etree._Element) -> dict[str, dict[str, Any]]:
    """label -> {value, U, k, p, unit} of every si:real that names its result.json key."""
    out = {}
    for real in root.iterfind(".//si:real", NS):
        label = real.findtext("si:label", None, NS)
        if not label:
            continue
        mu = real.find("si:measurementUncertaintyUnivariate/si:expandedMU", NS)
        out[label] = {
            "value": float(real.findtext("si:value", "", NS)),
            "unit": real.findtext("si:unit", "", NS),
            "U": None if mu is None else float(mu.findtext("si:valueExpandedMU", "", NS)),
            "k": None if mu is None else mu.findtext("si:coverageFactor", "", NS),
            "p": None if mu is None else mu.findtext("si:coverageProbability", "", NS),
        }
    return out


def _assert_value_u(reals: dict[str, dict[str, Any]], result: dict[str, Any], key: str,
                    u_key: str, unit: str, k: float = 2.0) -> None:
    """A value with its U, k = 2 or the t-factor its budget states, p = 95.45 %
    (docs/method.md D1)."""
    got = reals[key]
    assert got["value"] == _lookup(result, key), key
    assert got["U"] == _lookup(result, u_key), u_key
    assert (got["k"], got["p"], got["unit"]) == ("2" if k == 2.0 else f"{k:.2f}", "0.9545",
                                                 unit), key


# -- the schemas and the validator ---------------------------------------------------------

def test_shipped_schemas_are_ptbs_files_unmodified_with_their_licences() -> None:
    notice = (SCHEMAS / "NOTICE.md").read_text(encoding="utf-8")
    rows = re.findall(r"^\| `([^`]+)` \|.*\| ([0-9a-f]{64}) \|$", notice, re.M)
    shipped = {name: digest for name, digest in rows if not name.startswith("examples/")}
    assert len(shipped) == 6   # 4 schemas + LGPL-3.0 + GPL-3.0 texts
    for name, digest in shipped.items():
        assert hashlib.sha256((SCHEMAS / name).read_bytes()).hexdigest() == digest, name
    assert "GNU LESSER GENERAL PUBLIC LICENSE" in (SCHEMAS / "licenses" /
                                                    "COPYING.LESSER").read_text()


def test_the_invalid_public_example_is_refused_and_the_valid_ones_pass() -> None:
    bad = validate_dcc(EXAMPLES / "lutaml-sample-INVALID-3.3.0.xml")
    assert not bad.valid
    text = "\n".join(bad.lines())
    for expected in ("performanceLocation", "identifications", "expandedMU"):
        assert expected in text
    assert any("degreeCelsius" in line for line in bad.unit_errors)   # not D-SI: degreecelsius
    for good in ("minimal-rate-table-3.3.0.xml", "dcclib-valid-3.3.0.xml"):
        assert validate_dcc(EXAMPLES / good).valid, good
    done = _cli("verify", str(EXAMPLES / "lutaml-sample-INVALID-3.3.0.xml"), "--no-result")
    assert done.returncode == 1 and "FAIL  schema: 11 problem(s)" in done.stdout


def test_unit_strings_are_checked_beyond_the_schema() -> None:
    for ok in (r"\degree\second\tothe{-1}", r"\degree\hour\tothe{-1}", r"\one", r"\hertz",
               r"\hecto\pascal", r"\degreecelsius"):
        assert unit_problem(ok) is None, ok
    for bad in (r"\degreeCelsius", r"deg/s", r"\degree\second\tothe{x}", r"\hectopascal", ""):
        assert unit_problem(bad), bad
    # the XSD alone would accept a misspelt unit: the validator must not
    text = (EXAMPLES / "minimal-rate-table-3.3.0.xml").read_bytes().replace(
        rb"\degree\second\tothe{-1}", rb"\deg\second\tothe{-1}")
    v = validate_dcc(text)
    assert not v.schema_errors and v.unit_errors and not v.valid


def test_validation_needs_no_network() -> None:
    """In a network namespace with no network at all, the valid example passes and the
    invalid one is refused: nothing is fetched."""
    if shutil.which("unshare") is None or subprocess.run(
            ["unshare", "-rn", "true"], capture_output=True).returncode != 0:
        unavailable("no network namespace here (unshare -rn)")
    code = ("import sys; from pathlib import Path; from bench.app.dcc.validate import validate_dcc;"
            "ok = validate_dcc(Path(sys.argv[1])).valid; bad = validate_dcc(Path(sys.argv[2]));"
            "print(ok, bad.valid, len(bad.schema_errors))")
    done = subprocess.run(["unshare", "-rn", sys.executable, "-c", code,
                           str(EXAMPLES / "minimal-rate-table-3.3.0.xml"),
                           str(EXAMPLES / "lutaml-sample-INVALID-3.3.0.xml")],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.stdout.split() == ["True", "False", "9"], done.stderr


# -- the demo run --------------------------------------------------------------------------

@pytest.mark.timeout(400)
def test_demo_run_writes_a_valid_dcc(demo: dict[str, Any]) -> None:
    assert demo["status"] == 0, demo["stderr"][-2000:]
    path = demo["dir"] / "certificate.dcc.xml"
    assert "certificate.dcc.xml (valid DCC 3.3.0)" in demo["stderr"] + demo["stdout"]
    assert validate_dcc(path).valid
    assert _second_opinion(path) == []
    root = _tree(path)
    assert root.get("schemaVersion") == "3.3.0"
    core = root.find("dcc:administrativeData/dcc:coreData", NS)
    assert core.findtext("dcc:beginPerformanceDate", None, NS) == \
        demo["result"]["dates"]["started_utc"][:10]
    serial = root.find("dcc:administrativeData/dcc:items/dcc:item/dcc:identifications/"
                       "dcc:identification/dcc:value", NS)
    assert serial.text == demo["result"]["stand"]["serial"]
    pdf = root.find("dcc:document", NS)
    assert pdf.findtext("dcc:mimeType", None, NS) == "application/pdf"
    import base64
    assert base64.b64decode(pdf.findtext("dcc:dataBase64", "", NS)) == \
        (demo["dir"] / "certificate.pdf").read_bytes()
    digests = {t.findtext("dcc:name/dcc:content", None, NS): t.findtext("dcc:content", None, NS)
               for t in root.iterfind(".//dcc:text[@refType='ratebench_sha256']", NS)}
    assert digests == {f["path"]: f["sha256"] for f in demo["result"]["raw_files"]}
    defined = {d.text for d in root.iterfind(".//dcc:refTypeDefinition/dcc:namespace", NS)}
    used = {t.split("_")[0] for e in root.iter() for t in (e.get("refType") or "").split()}
    assert used <= defined == {"basic", "ratebench"}


def test_demo_every_value_and_u_equals_result_json(demo: dict[str, Any]) -> None:
    result, root = demo["result"], _tree(demo["dir"] / "certificate.dcc.xml")
    reals = _reals(root)
    for label, got in reals.items():          # every labelled number is result.json's
        assert got["value"] == _lookup(result, label), label
    n = 0
    for axis, ax in result["axes"].items():
        for i, r in enumerate(ax["rates"]):
            p = f"axes.{axis}.rates[{i}]"
            k_err = r["rate_error_budget"]["coverage_factor"]
            _assert_value_u(reals, result, f"{p}.rate_error_rel", f"{p}.rate_error_u_rel",
                            r"\one", k_err)
            # sigma: its chi-square interval or '< L', not +/- U (docs/method.md D2;
            # tests/test_budget_recompute.py checks the interval)
            assert reals[f"{p}.rate_instability_rel"]["U"] is None
            if r["intra_turn"].get("raw_resolved") is False:
                # not above the FOG floor: [0, raw + U], not +/- U (docs/method.md D2;
                # tests/test_budget_recompute.py checks the interval)
                assert reals[f"{p}.intra_turn_instability_rel"]["U"] is None
            else:
                _assert_value_u(reals, result, f"{p}.intra_turn_instability_rel",
                                f"{p}.intra_turn_instability_u_rel", r"\one")
            assert reals[f"{p}.set_rate_dps"]["unit"] == r"\degree\second\tothe{-1}"
            budget = [reals[f"{p}.rate_error_budget.{k}"]["value"]
                      for k in ("timing_u_rel", "timebase_u_rel", "repeatability_u_rel")]
            assert k_err * sum(u * u for u in budget) ** 0.5 == pytest.approx(   # U = k u_c
                reals[f"{p}.rate_error_rel"]["U"], rel=1e-9)
            for j in range(len(r["systematic"]["harmonics"])):
                h_p = f"{p}.systematic.harmonics[{j}]"
                if r["systematic"]["harmonics"][j].get("detected") is False:
                    # not detected: the DCC states the interval [0, L], not a +/- U
                    # (docs/method.md D2), as the PDF prints '< L'
                    assert reals[f"{h_p}.amplitude_rel"]["U"] is None
                else:
                    _assert_value_u(reals, result, f"{h_p}.amplitude_rel",
                                    f"{h_p}.amplitude_u_rel", r"\one")
                _assert_value_u(reals, result, f"{h_p}.phase_deg", f"{h_p}.phase_u_deg",
                                r"\degree")
            n += 1
        for i, _pair in enumerate(ax["pairs"]):
            p = f"axes.{axis}.pairs[{i}]"
            _assert_value_u(reals, result, f"{p}.k", f"{p}.k_u", r"\one")
            _assert_value_u(reals, result, f"{p}.w0_dps", f"{p}.w0_u_dps",
                            r"\degree\second\tothe{-1}")
    assert n == 10


def test_demo_per_turn_rates_are_lists_with_u_from_method_a1(demo: dict[str, Any]) -> None:
    result, root = demo["result"], _tree(demo["dir"] / "certificate.dcc.xml")
    lists = root.findall(".//dcc:quantity[@refType='basic_measuredValue ratebench_perTurnRate']",
                         NS)
    rates = [r for ax in result["axes"].values() for r in ax["rates"]]
    assert len(lists) == len(rates)
    for q, r in zip(lists, rates, strict=True):
        values = [float(x) for x in q.findtext("si:realListXMLList/si:valueXMLList", "",
                                               NS).split()]
        assert values == r["counter_rate_dps"]
        us = [float(x) for x in q.findtext(".//si:valueExpandedMUXMLList", "", NS).split()]
        b = r["rate_error_budget"]
        for w, u in zip(values, us, strict=True):   # docs/method.md A1 by hand: T = 360/|w|
            period = 360.0 / abs(w)
            assert u == pytest.approx(2 * abs(w) * ((b["period_u_s"] / period) ** 2
                                                    + b["timebase_u_rel"] ** 2) ** 0.5,
                                      rel=1e-12)


def test_demo_conformity_per_check_with_its_rule_and_limits(demo: dict[str, Any]) -> None:
    result, root = demo["result"], _tree(demo["dir"] / "certificate.dcc.xml")
    assert result["checks"]
    for i, c in enumerate(result["checks"], start=1):
        md = root.find(f".//dcc:metaData[@id='check_{i}']", NS)
        assert md is not None, i
        # a check left out of conformity (a sigma at the timing floor) states none
        expected = c["verdict"] if c["verdict"] in ("pass", "fail") else None
        assert md.findtext("dcc:conformity", None, NS) == expected
        assert md.findtext("dcc:norm", None, NS) == "ILAC-G8:09/2019"
        assert "guard" in md.findtext("dcc:reference", "", NS)
        def limit(ref: str, md: Any = md) -> float | None:
            q = md.find(f"dcc:data/dcc:quantity[@refType='{ref}']/si:real/si:value", NS)
            return None if q is None else float(q.text)


        # T is the tolerance; under guarded acceptance (w = U) a value is accepted within
        # T - U; a sigma has no lower limit and its upper limit is held against T
        assert limit("ratebench_toleranceLimitUpper") == c["tolerance_rel"]
        if c["quantity"] == "rate_error":
            assert limit("ratebench_toleranceLimitLower") == -c["tolerance_rel"]
            assert limit("basic_acceptanceLimitUpper") == c["tolerance_rel"] - c["U_rel"]
            assert limit("basic_acceptanceLimitLower") == -c["tolerance_rel"] + c["U_rel"]
        else:
            assert limit("ratebench_toleranceLimitLower") is None
            assert limit("basic_acceptanceLimitLower") is None
            assert limit("basic_acceptanceLimitUpper") == c["tolerance_rel"]
        judged = md.getparent().getparent()     # the quantity the check judges
        label = judged.findtext("si:real/si:label", "", NS)
        assert label.endswith(f"{c['quantity']}_rel")
        assert float(judged.findtext("si:real/si:value", "", NS)) == c["value_rel"]
    overall = root.find(".//dcc:statement[@id='overallConformity']", NS)
    assert overall.findtext("dcc:conformity", None, NS) == result["verdict"]


def test_bench_dcc_rewrites_and_bench_verify_accepts(demo: dict[str, Any]) -> None:
    path = demo["dir"] / "certificate.dcc.xml"
    before = path.read_bytes()
    path.unlink()
    done = _cli("dcc", str(demo["dir"]))
    assert done.returncode == 0, done.stderr
    assert validate_dcc(path).valid
    assert _reals(_tree(path)) == _reals(etree.fromstring(before, etree.XMLParser(
        huge_tree=True)))
    ok = _cli("verify", str(path))
    assert ok.returncode == 0, ok.stdout + ok.stderr
    assert "verify: OK" in ok.stdout and "not signed" in ok.stdout
    core = _tree(path).find("dcc:administrativeData/dcc:coreData", NS)
    pdf_text = (demo["dir"] / "certificate.html").read_text(encoding="utf-8")
    assert core.findtext("dcc:uniqueIdentifier", "", NS) in pdf_text   # the PDF's number


def _copy_run(run: dict[str, Any], dest: Path) -> Path:
    """The run directory without its raw data (the DCC lists their digests from result.json)."""
    dest.mkdir()
    for name in ("result.json", "stand.yaml", "procedure.yaml", "meta.json", "events.jsonl",
                 "certificate.pdf"):
        shutil.copy2(run["dir"] / name, dest / name)
    return dest


def test_a_dcc_that_does_not_validate_exits_3(demo: dict[str, Any], tmp_path: Path) -> None:
    run = _copy_run(demo, tmp_path / "run")
    result = json.loads((run / "result.json").read_text())
    result["certificate"]["performance_location"] = "on the moon"   # not in the DCC's list
    (run / "result.json").write_text(json.dumps(result))
    done = _cli("dcc", str(run))
    assert done.returncode == 3
    assert "NOT valid" in done.stderr and "performanceLocation" in done.stderr
    assert not (run / "certificate.dcc.xml").exists()
    assert (run / "certificate.dcc.invalid.xml").exists()


def test_verify_finds_a_value_changed_in_an_unsigned_file(demo: dict[str, Any],
                                                          tmp_path: Path) -> None:
    run = _copy_run(demo, tmp_path / "run")
    assert _cli("dcc", str(run)).returncode == 0
    path = run / "certificate.dcc.xml"
    r0 = demo["result"]["axes"]["outer"]["rates"][0]
    text = path.read_text(encoding="utf-8")
    old = f"<si:value>{r0['rate_error_rel']!r}</si:value>"
    assert text.count(old) == 2      # the result, then its budget's estimate (annex)
    path.write_text(text.replace(old, "<si:value>0.0</si:value>", 1), encoding="utf-8")
    done = _cli("verify", str(path))
    assert done.returncode == 1
    assert "r_outer_p10_rate_error_rel: value (0.0,)" in done.stdout


# -- signing -------------------------------------------------------------------------------

def _throwaway_key(folder: Path, cn: str) -> tuple[Path, Path]:
    """A fresh EC key and self-signed certificate for this test only, outside any run."""
    folder.mkdir(parents=True, exist_ok=True)
    key = ec.generate_private_key(ec.SECP256R1())
    subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, cn)])
    now = dt.datetime.now(dt.UTC)
    cert = (x509.CertificateBuilder().subject_name(subject).issuer_name(subject)
            .public_key(key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(now - dt.timedelta(days=1))
            .not_valid_after(now + dt.timedelta(days=30)).sign(key, hashes.SHA256()))
    key_file, cert_file = folder / "dcc.key.pem", folder / "dcc.cert.pem"
    key_file.write_bytes(key.private_bytes(serialization.Encoding.PEM,
                                           serialization.PrivateFormat.PKCS8,
                                           serialization.BestAvailableEncryption(b"s3cret")))
    cert_file.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    return key_file, cert_file


def _lab_file(folder: Path, key: Path, cert: Path) -> Path:
    lab = folder / "lab.yaml"
    lab.write_text(f"""\
laboratory:
  name: Test Rate Lab
  code: D-K-00000-01
  email: lab@example.org
  location: {{street: Example Street, street_no: "1", post_code: "00000", city: Example City,
              country_code: DE}}
country_code: DE
responsible_persons:
  - {{name: A. Tester, role: Calibration performed by, main_signer: true}}
signing: {{key: {key}, certificate: {cert}, password_env: TEST_DCC_KEY_PASSWORD}}
""")
    return lab


@pytest.fixture
def signed(drift: dict[str, Any], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
           ) -> dict[str, Path]:
    assert drift["status"] == 0, drift["stderr"][-2000:]
    key, cert = _throwaway_key(tmp_path / "keys", "Test Rate Lab DCC signing")
    lab = _lab_file(tmp_path, key, cert)
    run = _copy_run(drift, tmp_path / "run")
    monkeypatch.setenv("TEST_DCC_KEY_PASSWORD", "s3cret")
    designate(add_register(lab, tmp_path / "register"), cert)
    done = authorise(run, "A. Tester", lab)
    assert done.returncode == 0, done.stderr
    assert "DCC signed (XAdES)" in done.stdout
    return {"run": run, "lab": lab, "cert": cert, "file": run / "certificate.dcc.xml"}


def test_drift_demo_dcc_validates_and_carries_every_value(drift: dict[str, Any]) -> None:
    assert drift["status"] == 0, drift["stderr"][-2000:]
    path = drift["dir"] / "certificate.dcc.xml"
    assert validate_dcc(path).valid
    assert _second_opinion(path) == []
    result, reals = drift["result"], _reals(_tree(path))
    for label, got in reals.items():
        assert got["value"] == _lookup(result, label), label
    root = _tree(path)
    budget_u = {r.findtext("dcc:name/dcc:content", "", NS): float(r.findtext(
        ".//dcc:quantity[@id='" + r.get("id") + "_U']/si:real/si:value", "", NS))
        for r in root.iterfind(".//dcc:result[@refType='ratebench_uncertaintyBudget']", NS)}
    for axis, ax in result["drift"]["axes"].items():
        p = f"drift.axes.{axis}"
        # U = k(nu_eff) u_c of its budget, one rule with the rate ladder (docs/method.md D1)
        _assert_value_u(reals, result, f"{p}.own_dph", f"{p}.own_u_dph",
                        r"\degree\hour\tothe{-1}", k=ax["own_coverage_factor"])
        _assert_value_u(reals, result, f"{p}.apparent_dph", f"{p}.apparent_u_dph",
                        r"\degree\hour\tothe{-1}", k=ax["apparent_coverage_factor"])
        assert budget_u[f"own drift ω_own ({axis}), axis {axis}"] == reals[f"{p}.own_dph"]["U"]
    _assert_value_u(reals, result, "drift.azimuth_deg", "drift.azimuth_u_deg", r"\degree",
                    k=result["drift"]["azimuth_coverage_factor"])
    assert budget_u["platform azimuth A, overall"] == reals["drift.azimuth_deg"]["U"]
    for i, c in enumerate(result["checks"], start=1):
        md = root.find(f".//dcc:metaData[@id='check_{i}']", NS)
        assert md.findtext("dcc:conformity", None, NS) == c["verdict"]


def test_signed_dcc_verifies_and_keeps_the_key_out_of_the_run(signed: dict[str, Path]) -> None:
    root = _tree(signed["file"])
    sig = root[-1]
    assert sig.tag == f"{{{NS['ds']}}}Signature"
    assert sig.find(".//{http://uri.etsi.org/01903/v1.3.2#}SigningCertificateV2") is not None
    assert sig.find(".//{http://uri.etsi.org/01903/v1.3.2#}SigningTime") is not None
    assert validate_dcc(signed["file"]).valid
    lab = root.find("dcc:administrativeData/dcc:calibrationLaboratory", NS)
    assert lab.findtext("dcc:calibrationLaboratoryCode", None, NS) == "D-K-00000-01"
    files = [f for f in signed["run"].rglob("*") if f.is_file()]
    assert signed["file"] in files, files
    for f in files:
        assert b"PRIVATE KEY" not in f.read_bytes(), f
    done = _cli("verify", str(signed["file"]), "--cert", str(signed["cert"]))
    assert done.returncode == 0, done.stdout + done.stderr
    assert "signature: XAdES verifies; signer CN=Test Rate Lab DCC signing" in done.stdout
    assert "values: all" in done.stdout


def test_tampered_signed_dcc_fails_verify(signed: dict[str, Path], tmp_path: Path) -> None:
    text = signed["file"].read_text(encoding="utf-8")
    own = json.loads((signed["run"] / "result.json").read_text())["drift"]["axes"]["x"]["own_dph"]
    old = f"<si:value>{own!r}</si:value>"
    assert text.count(old) == 1      # the result (its budget's inputs are the position means)
    signed["file"].write_text(text.replace(old, f"<si:value>{own + 0.1!r}</si:value>", 1),
                              encoding="utf-8")
    done = _cli("verify", str(signed["file"]), "--cert", str(signed["cert"]))
    assert done.returncode == 1
    assert "signature: does NOT verify" in done.stdout
    # an untouched file, but the trusted certificate is not the signer's: refused too
    _other_key, other_cert = _throwaway_key(tmp_path / "other", "Someone else")
    signed["file"].write_text(text, encoding="utf-8")             # untouched again
    done = _cli("verify", str(signed["file"]), "--cert", str(other_cert))
    assert done.returncode == 1 and "does NOT verify" in done.stdout   # not the lab's key


def test_a_key_inside_the_run_directory_is_refused(drift: dict[str, Any], tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    run = _copy_run(drift, tmp_path / "run")
    key, cert = _throwaway_key(run / "keys", "careless")
    monkeypatch.setenv("TEST_DCC_KEY_PASSWORD", "s3cret")
    assert _cli("dcc", str(run)).returncode == 0                    # the draft, unsigned
    draft = (run / "certificate.dcc.xml").read_bytes()
    lab = _lab_file(tmp_path, key, cert)
    designate(add_register(lab, tmp_path / "register"), cert)
    done = authorise(run, "A. Tester", lab)
    assert done.returncode == 2
    assert "lies inside the run directory" in done.stderr
    assert (run / "certificate.dcc.xml").read_bytes() == draft     # nothing issued
    assert not (run / "issued").exists()


# -- the laboratory's settings -------------------------------------------------------------

def test_stand_dcc_key_refuses_relative_and_pasted_keys(tmp_path: Path) -> None:
    """`bench validate` names file, line and key of a key path that is relative or of a
    key pasted into the stand file (the stand file travels into every run directory)."""
    (tmp_path / "stands").mkdir()
    (tmp_path / "procedures").mkdir()
    stand = tmp_path / "stands" / "sim-two-axis.yaml"
    proc = tmp_path / "procedures" / "demo.yaml"
    shutil.copy(CONFIGS / "procedures" / "demo.yaml", proc)
    text = (CONFIGS / "stands" / "sim-two-axis.yaml").read_text()
    line = text.count("\n") + 3     # a blank line, `dcc:`, then `signing:`
    stand.write_text(text + "\ndcc:\n  signing: {key: keys/lab.pem, certificate: "
                            "'-----BEGIN CERTIFICATE----- MIIB...'}\n")
    done = _cli("validate", str(proc))
    assert done.returncode == 2
    assert f"{stand}:{line}: dcc.signing.key: expected an absolute path" in done.stderr
    assert "dcc.signing.certificate: expected the path of a PEM file" in done.stderr
    stand.write_text(text + f"\ndcc:\n  signing: {{key: {tmp_path}/k.pem, "
                            f"certificate: {tmp_path}/c.pem}}\n")
    assert _cli("validate", str(proc)).returncode == 0


def test_lab_file_problems_name_file_line_and_key(demo: dict[str, Any], tmp_path: Path) -> None:
    lab = tmp_path / "lab.yaml"
    lab.write_text("laboratory: {name: Lab}\ncountry_code: Germany\nperformance_location: moon\n"
                   "signing: {key: relative.pem}\n")
    run = _copy_run(demo, tmp_path / "run")
    done = _cli("dcc", str(run), "--lab", str(lab))
    assert done.returncode == 3
    for where in (f"{lab}:2: country_code: expected an ISO 3166-1 alpha-2 code",
                  f"{lab}:3: performance_location: expected one of laboratory",
                  f"{lab}:4: signing.key: expected an absolute path",
                  f"{lab}:4: signing: missing required key 'certificate'"):
        assert where in done.stderr, where
    assert not (run / "certificate.dcc.xml").exists()


def test_lab_settings_fill_the_administrative_data(demo: dict[str, Any], tmp_path: Path) -> None:
    key, cert = _throwaway_key(tmp_path / "keys", "unused")
    lab = _lab_file(tmp_path, key, cert)
    lab.write_text(lab.read_text().split("signing:")[0])           # the same lab, unsigned
    run = _copy_run(demo, tmp_path / "run")
    assert _cli("dcc", str(run), "--lab", str(lab)).returncode == 0     # the draft
    draft = _tree(run / "certificate.dcc.xml").find("dcc:administrativeData", NS)
    person = draft.find("dcc:respPersons/dcc:respPerson", NS)
    # the performer: no account authenticated at the run's start (issue 42), whatever
    # names the lab file lists
    assert person.findtext("dcc:person/dcc:name/dcc:content", None, NS) == "not recorded"
    assert person.find("dcc:mainSigner", NS) is None                  # nobody authorised it
    add_register(lab, tmp_path / "register")
    done = authorise(run, "A. Tester", lab)
    assert done.returncode == 0, done.stderr
    root = _tree(run / "certificate.dcc.xml")
    adm = root.find("dcc:administrativeData", NS)
    assert adm.findtext("dcc:coreData/dcc:countryCodeISO3166_1", None, NS) == "DE"
    contact = adm.find("dcc:calibrationLaboratory/dcc:contact", NS)
    assert contact.findtext("dcc:name/dcc:content", None, NS) == "Test Rate Lab"
    assert contact.findtext("dcc:location/dcc:city", None, NS) == "Example City"
    performer, signer = adm.findall("dcc:respPersons/dcc:respPerson", NS)
    assert performer.findtext("dcc:person/dcc:name/dcc:content", None, NS) == "not recorded"
    assert performer.find("dcc:mainSigner", NS) is None
    assert signer.findtext("dcc:person/dcc:name/dcc:content", None, NS) == "A. Tester"
    assert signer.findtext("dcc:mainSigner", None, NS) == "true"
    assert root.find(".//ds:Signature", NS) is None
    assert root.find(".//dcc:statement[@refType='ratebench_countryNotConfigured']", NS) is None


def test_a_damaged_result_still_gives_a_valid_dcc(demo: dict[str, Any]) -> None:
    """Each top-level key of result.json removed, each key of its first rate, pair and
    check replaced by text: the writer neither crashes nor writes an invalid DCC (it leaves
    the damaged value out; `bench verify` would then name it). Dropping `axes` once gave
    a DCC without any measurementResult, which the schema refuses."""
    from bench.app.dcc.writer import DccInputs, build_dcc
    from bench.report.certificate.sources import Sources

    result = copy.deepcopy(demo["result"])
    ax = result["axes"]["outer"]
    places = [(result, k, "drop") for k in result]
    for part in (ax["rates"][0], ax["pairs"][0], result["checks"][0]):
        places += [(part, k, "text") for k in part]
    assert len(places) > 60
    for node, key, damage in places:
        saved = node[key]
        if damage == "drop":
            del node[key]
        else:
            node[key] = "garbage"
        try:
            v = validate_dcc(build_dcc(DccInputs(Sources.load(result, None), embed_pdf=False)))
        finally:
            node[key] = saved
        assert v.valid, (key, damage, v.lines()[:3])


def test_which_lab_settings_and_key_are_in_force(tmp_path: Path,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """--lab, then the stand's dcc.lab, then $BENCH_LAB_SETTINGS; a key named in the stand
    file overrides the lab file's."""
    from bench.app.dcc.settings import resolve_settings
    from bench.core.config import dcc_refs

    key, cert = _throwaway_key(tmp_path / "keys", "lab")
    (tmp_path / "a").mkdir()
    first = _lab_file(tmp_path / "a", key, cert)
    second = tmp_path / "b.yaml"
    second.write_text("laboratory: {name: Second Lab}\n")
    assert resolve_settings(dcc_refs({})).laboratory is None       # nothing configured
    monkeypatch.setenv(ENV_LAB, str(second))
    assert resolve_settings(dcc_refs({})).laboratory.name == "Second Lab"
    stated = dcc_refs({"dcc": {"lab": str(first)}})
    assert resolve_settings(stated).laboratory.name == "Test Rate Lab"
    assert resolve_settings(stated, lab_file=second).laboratory.name == "Second Lab"
    own = {"key": str(tmp_path / "stand.key.pem"), "certificate": str(cert)}
    chosen = resolve_settings(dcc_refs({"dcc": {"lab": str(first), "signing": own}}))
    assert chosen.laboratory.name == "Test Rate Lab"
    assert chosen.signing.key_file == tmp_path / "stand.key.pem"
    assert resolve_settings(stated).signing.key_file == key
