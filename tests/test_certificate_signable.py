"""Issue 18: a certificate a 17025 laboratory can sign.

Each test reads the certificate as a reader would (the rendered HTML, and the PDF's own
text) and checks it against a truth worked out independently of the certificate code:
the per-turn rates are built from edge times with a known mean, the item from the stand
file shipped in configs/, the numbering from the register on disk.
"""

from __future__ import annotations

import datetime as dt
import html as html_lib
import re
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pypdfium2 as pdfium
import pytest

from bench.analysis.turns import CounterBudget, analyze_turns
from bench.app.certificate import render_files, write_certificate
from bench.app.certificate.build import build_document
from bench.app.certificate.html import render_html
from bench.app.certificate.register import REGISTER_NAME, issues, next_issue, record
from bench.core.journal import RunDir
from bench.report.certificate.sources import Sources
from bench.report.codec import encode
from procedures.drift_pulse.sample import drift_pulse_result
from procedures.rate_ladder.result import turns_entry

ROOT = Path(__file__).resolve().parents[1]
ISSUED = dt.date(2026, 11, 22)
MINUS = "\u2212"


def _run_dir(path: Path) -> RunDir:
    (path / "events.jsonl").touch()
    return RunDir(path)


def _cells(html: str, caption_start: str) -> list[list[str]]:
    """The body rows of the table whose caption starts with `caption_start`."""
    i = html.index(caption_start)
    body = html[html.index("<tbody>", i):html.index("</tbody>", i)]
    rows = re.findall(r"<tr>(.*?)</tr>", body, flags=re.S)
    return [[html_lib.unescape(re.sub(r"<[^>]+>", "", c)).strip()
             for c in re.findall(r"<td[^>]*>(.*?)</td>", r, flags=re.S)] for r in rows]


def _number(text: str) -> float:
    return float(text.replace(MINUS, "-").replace("+", ""))


# -- one sign convention, printed as computed ------------------------------------------------

def _ladder_result(truth_rel: dict[float, float]) -> dict[str, Any]:
    """Per-turn results from edge times whose mean rate is set * (1 + truth)."""
    budget = CounterBudget(timestamp_u_s=2e-11, trigger_jitter_s=2.7e-8,
                           timebase_limit_rel=1e-9)
    rates = []
    for set_dps, rel in truth_rel.items():
        period = 360.0 / (abs(set_dps) * (1 + rel))
        wobble = np.array([0.0, 3e-7, -2e-7, 1e-7, 0.0]) * period
        edges = 100.0 + np.arange(5) * period + wobble
        rates.append(encode(turns_entry(analyze_turns([edges], set_dps, budget))))
    return {"schema": "bench.result/1", "procedure": "rate-ladder", "verdict": "pass",
            "axes": {"outer": {"rates": rates, "pairs": []}}}


def _printed_formula(html: str) -> str:
    """The right-hand side of eq. 1 as printed."""
    line = next(m for m in re.findall(r'<p class="formula">(.*?)</p>', html, flags=re.S)
                if "eq. 1" in m)
    rhs = html_lib.unescape(line).split("=", 1)[1].split("(eq. 1")[0].strip()
    return rhs


def _apply(formula: str, mean: float, set_rate: float) -> float:
    """Evaluate the printed formula on printed inputs: its symbols and bars, nothing else."""
    expr = formula.replace("mean(ω_i)", "m").replace("ω_set", "s").replace(MINUS, "-")
    expr = re.sub(r"\|([^|]+)\|", r"abs(\1)", expr)
    assert re.fullmatch(r"[ms()+\-*/ absx]+", expr), expr
    return float(eval(expr, {"abs": abs}, {"m": mean, "s": set_rate}))  # noqa: S307


def test_printed_formula_on_printed_inputs_gives_printed_delta() -> None:
    # truth: slower than commanded by 0.12 ppm at -10 deg/s, faster by 0.25 ppm at +10
    result = _ladder_result({10.0: 2.5e-7, -10.0: -1.2e-7})
    html = render_html(build_document(Sources.load(result, None), ISSUED))
    formula = _printed_formula(html)
    rows = _cells(html, "Axis outer: per-turn rate error and instability")
    assert [r[0] for r in rows] == ["+10", f"{MINUS}10"]
    for row, truth in zip(rows, (2.5e-7, -1.2e-7), strict=True):
        set_rate = _number(row[0])
        mean_text, _ = row[2].split(" ± ")
        delta_text, delta_u = row[3].split(" ± ")
        mean, delta_ppm = _number(mean_text), _number(delta_text)
        recomputed_ppm = _apply(formula, mean, set_rate) * 1e6
        # the printed mean is rounded to its last digit: half of it, relative to |set|
        last = 10.0 ** -len(mean_text.split(".")[1]) if "." in mean_text else 1.0
        slack = 0.5 * last / abs(set_rate) * 1e6 + 0.5 * 10.0 ** -len(
            delta_text.split(".")[1])
        assert abs(recomputed_ppm - delta_ppm) <= slack, (row, formula)
        assert np.sign(delta_ppm) == np.sign(truth)         # the sign of the truth
        assert abs(delta_ppm - truth * 1e6) <= _number(delta_u)


def test_per_edge_timing_and_the_coverage_rule_are_printed() -> None:
    """The method section renders the Type A term and the coverage factor from the
    constants the analysis computes with (docs/method.md A2, D1)."""
    from bench.analysis.coverage import COVERAGE_FORMULA
    from bench.analysis.turns import REPEATABILITY_FORMULA

    html = html_lib.unescape(render_html(build_document(
        Sources.load(_ladder_result({10.0: 1e-7}), None), ISSUED)))
    assert "Δ_edge = √(Δ_counter² + Δ_trigger²);   ΔT = √2 · Δ_edge" in html
    assert REPEATABILITY_FORMULA in html and COVERAGE_FORMULA in html
    assert "(N − 3)" not in html


# -- the item is what was calibrated -----------------------------------------------------

def test_drift_certificate_item_is_the_platform_with_its_gyros(tmp_path: Path) -> None:
    run = _run_dir(tmp_path)
    shutil.copyfile(ROOT / "configs/stands/sim-gyro-platform.yaml", run.path / "stand.yaml")
    result = encode(drift_pulse_result())
    result["stand"] = {"maker": "Simulated Gyro Lab", "model": "GP-3 platform test stand",
                       "serial": "SIM-0004", "simulated": True}
    write_certificate(run, Sources.load(result, run.path), issued=ISSUED)
    html = (run.path / "certificate.html").read_text(encoding="utf-8")
    item: dict[str, str] = {}
    for k, v in _fields(html):   # section 1 (Identification) first
        item.setdefault(k, v)
    assert item["Item calibrated"] == (
        "Simulated Gyro Works TGS-3 three-axis gyrostabiliser, with its gyros (x: TG-1 "
        "floated rate-integrating gyro, serial SIM-G-0711; y: TG-1 floated rate-integrating "
        "gyro, serial SIM-G-0712)")
    assert item["Serial number"] == "SIM-P-0070"
    assert "SIM-0004" in item["Test stand used"]
    assert "describe no physical table" not in html


def _fields(html: str) -> list[tuple[str, str]]:
    rows = re.findall(r"<tr><td>(.*?)</td><td[^>]*>(.*?)</td></tr>", html, flags=re.S)
    return [(html_lib.unescape(k), html_lib.unescape(v)) for k, v in rows]


# -- document control -------------------------------------------------------------------

def _pdf_text(path: Path) -> list[str]:
    return [p.get_textpage().get_text_range() for p in pdfium.PdfDocument(path)]


def test_drafts_are_not_issues_and_name_the_revision_they_would_become(
        tmp_path: Path) -> None:
    """`bench run` / `bench analyze` write drafts: no issue is recorded, so writing one
    twice gives the same draft number; once revision 1 is issued (bench authorise records
    it), the next draft is revision 2's and claims nothing withdrawn yet."""
    run = _run_dir(tmp_path)
    result = _ladder_result({10.0: 1e-7})
    result.update(run_dir=run.path.name, dates={"created_utc": "2026-11-22T10:00:00Z",
                                                "completed_utc": "2026-11-22T11:00:00Z"})
    write_certificate(run, Sources.load(result, run.path), issued=ISSUED)
    first = re.search(r"Draft (DRAFT-\S+)", _pdf_text(run.path / "certificate.pdf")[0])[1]
    write_certificate(run, Sources.load(result, run.path), issued=ISSUED + dt.timedelta(days=1))
    pages = _pdf_text(run.path / "certificate.pdf")
    assert re.search(r"Draft (DRAFT-\S+)", pages[0])[1] == first
    assert len(pages) > 2 and all("DRAFT, NOT AUTHORISED" in p for p in pages)
    assert issues(run.path) == [] and not (run.path / REGISTER_NAME).exists()
    record(run.path, next_issue(run.path, first, dt.datetime(2026, 11, 23, 9, tzinfo=dt.UTC),
                                signatory="P. Petrov"))
    write_certificate(run, Sources.load(result, run.path))
    text = re.sub(r"\s+", " ", " ".join(_pdf_text(run.path / "certificate.pdf")))
    assert f"Draft {first}-R2" in text
    assert "which is withdrawn" not in text
    assert f"DRAFT of a re-issue; certificate {first} stands until it is issued" in text


def test_simulated_run_is_marked_on_every_page(tmp_path: Path) -> None:
    run = _run_dir(tmp_path)
    result = _ladder_result({10.0: 1e-7, -10.0: 1e-7})
    result["stand"] = {"maker": "Sim", "model": "ST", "serial": "S1", "simulated": True}
    write_certificate(run, Sources.load(result, run.path), issued=ISSUED)
    pages = _pdf_text(run.path / "certificate.pdf")
    assert len(pages) > 2
    assert all("SIMULATED RUN: NOT A CALIBRATION" in p for p in pages)
    real = _run_dir(tmp_path / "real") if (tmp_path / "real").mkdir() is None else None
    result["stand"]["simulated"] = False
    write_certificate(real, Sources.load(result, real.path), issued=ISSUED)
    assert not any("SIMULATED" in p for p in _pdf_text(real.path / "certificate.pdf"))


def test_named_signatories_from_the_lab_settings(tmp_path: Path) -> None:
    import yaml

    run = _run_dir(tmp_path)
    lab = yaml.safe_load((ROOT / "configs/lab.yaml").read_text())
    result = _ladder_result({10.0: 1e-7})
    result["certificate"] = lab
    write_certificate(run, Sources.load(result, run.path), issued=ISSUED)
    text = re.sub(r"\s+", " ", "".join(_pdf_text(run.path / "certificate.pdf")))
    # names in a lab file sign nothing (issue 42): the performer is an authenticated
    # account or "not recorded"
    assert "A. Ivanova" not in text
    assert "Calibration performed by: not recorded (no account authenticated" in text
    assert "Date of issue:" not in text and "authorised for issue by" not in text  # a draft
    issue = next_issue(run.path, "RT-TEST", dt.datetime(2026, 11, 22, 9, tzinfo=dt.UTC),
                       signatory="P. Petrov", function="Technical manager (authorised "
                       "signatory)")
    render_files(Sources.load(result, run.path), run.path, issue=issue)
    text = re.sub(r"\s+", " ", "".join(_pdf_text(run.path / "certificate.pdf")))
    assert ("Date of issue: 2026-11-22, the date on which this certificate was authorised "
            "for issue by P. Petrov, Technical manager (authorised signatory)") in text
    assert "1 Example Street" in text
    assert "certificate.pdf is the authoritative form" in text


@pytest.mark.parametrize("lab, message", [
    ("3", "certificate.lab: expected the path of a lab settings file"),
    ("nowhere.yaml", "certificate.lab: lab settings file"),
])
def test_a_bad_lab_key_is_named_by_file_line_and_key(tmp_path: Path, lab: str,
                                                     message: str) -> None:
    from bench.core.config import ConfigError
    from bench.core.loader import load_config

    proc = (ROOT / "configs/procedures/demo.yaml").read_text()
    proc = proc.replace("stand: ../stands/", f"stand: {ROOT}/configs/stands/")
    proc = proc.replace("  customer: Demo customer", f"  lab: {lab}\n  customer: Demo customer")
    (tmp_path / "p.yaml").write_text(proc)
    line = proc[:proc.index(f"  lab: {lab}")].count("\n") + 1
    with pytest.raises(ConfigError) as e:
        load_config(tmp_path / "p.yaml")
    assert f"p.yaml:{line}: {message}" in str(e.value)


def test_a_lab_file_is_read_and_copied_into_the_run(tmp_path: Path) -> None:
    """`certificate: {lab: FILE}`: its keys under the procedure's own, kept with the run."""
    from bench.core.lab import certificate_settings, lab_path

    proc = tmp_path / "p.yaml"
    shutil.copyfile(ROOT / "configs/lab.yaml", tmp_path / "lab.yaml")
    cert = {"lab": "lab.yaml", "customer": "C"}
    assert lab_path(proc, cert) == tmp_path / "lab.yaml"
    merged = certificate_settings(proc, cert)
    assert merged["customer"] == "C" and merged["address"].startswith("1 Example Street")
    assert [s["name"] for s in merged["signatories"]] == ["A. Ivanova", "P. Petrov"]
    # in a run directory, the copy made when the run started is the one read
    run = tmp_path / "run"
    run.mkdir()
    (run / "meta.json").write_text("{}")
    assert lab_path(run / "procedure.yaml", cert) is None      # no copy: not guessed
    shutil.copyfile(ROOT / "configs/lab.yaml", run / "lab.yaml")
    assert lab_path(run / "procedure.yaml", cert) == run / "lab.yaml"


# -- a sigma at the timing floor -----------------------------------------------------------

def test_sigma_below_the_timing_floor_is_flagged_and_left_out_of_conformity() -> None:
    """Edges with 1 us of jitter over 5 turns at 360 deg/s (T = 1 s): the timing floor is
    sqrt(2) * 1e-6 = 1.41 ppm; the turn-to-turn scatter built in is 0.1 ppm, far below it."""
    import msgspec

    from procedures.rate_ladder.analysis import sigma_check, with_sigma_terms

    budget = CounterBudget(timestamp_u_s=0.0, trigger_jitter_s=1e-6, timebase_limit_rel=0.0)
    edges = 10.0 + np.arange(6) * 1.0 + np.array([0, 1e-7, -1e-7, 1e-7, -1e-7, 0])
    d = with_sigma_terms(turns_entry(analyze_turns([edges], 360.0, budget)))
    assert d.rate_instability_floor_rel is not None and d.rate_instability_rel is not None
    assert abs(d.rate_instability_floor_rel - 2 ** 0.5 * 1e-6) < 1e-12
    assert d.rate_instability_rel < d.rate_instability_floor_rel
    assert d.rate_instability_resolved is False
    check = sigma_check("outer", 360.0, d, 1e-7, "guard-band")   # a tolerance it exceeds
    assert check.verdict == "not-assessed"                    # not a FAIL, not a PASS
    assert "timing floor" in check.reason
    result = {"schema": "bench.result/1", "procedure": "rate-ladder", "verdict": "pass",
              "decision_rule": "guard-band", "checks": [encode(check)],
              "axes": {"outer": {"rates": [encode(msgspec.structs.replace(d, verdict="pass"))],
                                 "pairs": []}}}
    html = html_lib.unescape(render_html(build_document(Sources.load(result, None), ISSUED)))
    row = _cells(html, "Axis outer: per-turn rate error and instability")[0]
    assert d.rate_instability_upper_rel is not None
    limit_ppm = d.rate_instability_upper_rel * 1e6
    assert row[4].startswith("< ") and float(row[4][2:]) >= limit_ppm   # a limit, rounded up
    conf = _cells(html, "Conformity with the specification")[0]
    assert conf[-1] == "NOT ASSESSED" and "(timing floor)" in conf[4]
    assert "NO STATEMENT OF CONFORMITY: none of the 1 check(s) could be assessed" in html
