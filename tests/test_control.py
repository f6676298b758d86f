"""Measurement assurance (issue 28): control charts of the bench's own instruments.

The acceptance test reads short simulated runs of the two-axis twin (one axis, one
rate, two turns): those of the session's `control_baseline` (tests/conftest.py; as many
as the pytest setting control_baseline_runs, 8 in pyproject.toml, at least the records'
BASELINE_RUNS), with a stable FOG, copied with their records, then one of its own whose FOG scale is stepped by ten times the U of its k (the stand's
`sim.axes.outer.fog.scale_step`, the run number taken from the records). `bench control` must flag that FOG with the rule, the refusal function
`bench authorise` will call must name the rule, a recorded review must lift the refusal,
and the certificate must state the review. The rules themselves are checked on series
built by hand, each rule broken alone.
"""

from __future__ import annotations

import datetime as dt
import json
import re
import statistics
from pathlib import Path
from typing import Any

import pytest
import yaml

from bench.app.records.assurance import assurance_refusals, warn_at_start
from bench.app.records.checks import CheckRecord
from bench.app.records.control import (
    BASELINE_RUNS,
    IN_CONTROL,
    NOT_ENOUGH,
    OUT_OF_CONTROL,
    charts,
    status_of,
)
from bench.app.records.hooks import target
from bench.app.records.store import CheckPoint, ReviewInfo
from bench.core.config import parse_stand
from bench.core.simdrift import drifted
from tests.conftest import (
    CONFIGS,
    ControlBaseline,
    check_procedure,
    check_run,
    cli,
    unavailable,
)
from tests.conftest import OUTER_SERIALS as OUTER
from tests.registers import add_register, authorise, cli_in, password

FOG = OUTER["fog"]

@pytest.fixture(scope="module")
def history(control_baseline: ControlBaseline,
            tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The session's baseline runs copied (with their records) into a runs folder of this
    module's, then run 9 (one past the baseline): its FOG's scale stepped from that
    run of the records on."""
    stable = control_baseline.size     # the pytest setting control_baseline_runs
    assert stable >= BASELINE_RUNS, f"control_baseline_runs = {stable}: the charts judge a " \
        f"run after a baseline of {BASELINE_RUNS} (bench/app/records/control.py)"
    folder = tmp_path_factory.mktemp("assurance")
    runs = folder / "runs"
    dirs = control_baseline.copy_to(runs)
    pairs = [json.loads((d / "result.json").read_text())["axes"]["outer"]["pairs"][0]
             for d in dirs]
    k_u = statistics.median(p["k_u"] for p in pairs)
    k = statistics.fmean(p["k"] for p in pairs)
    step_rel = 10 * k_u / k                       # k = scale cos(g): ten times U of k
    shifted, out = check_run(check_procedure(folder, 100, (stable + 1, step_rel)), runs)
    return {"folder": folder, "runs": runs, "dirs": dirs, "shifted": shifted, "k_u": k_u,
            "k": k, "step_rel": step_rel, "out9": out, "pairs": pairs, "stable": stable}


def _html_text(run_dir: Path) -> str:
    html = (run_dir / "certificate.html").read_text(encoding="utf-8")
    return re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", html))


@pytest.mark.timeout(900)
def test_a_fog_scale_step_of_ten_u_is_flagged_refused_reviewed_and_certified(
        history: dict[str, Any], tmp_path: Path) -> None:
    runs, shifted = history["runs"], history["shifted"]
    # the twin drifted in the run after the baseline (its number from the records), by the
    # step asked for
    run_number = json.loads((shifted / "meta.json").read_text())["sim_run_number"]
    assert run_number == history["stable"] + 1
    assert "sim_run_number" not in json.loads((history["dirs"][0] / "meta.json").read_text())
    k9 = json.loads((shifted / "result.json").read_text())["axes"]["outer"]["pairs"][0]
    assert abs(k9["k"] - history["k"] * (1 + history["step_rel"])) < 3 * history["k_u"]

    # the first run's certificate: not enough history, with the count, per instrument
    first = _html_text(history["dirs"][0])
    for role in ("fog", "counter", "drive"):
        assert re.search(rf"Measurement assurance \(ISO/IEC 17025 7\.7\), {role} "
                         rf"{OUTER[role]}[^.]*: not enough history \(1 of "
                         rf"{BASELINE_RUNS} runs", first), role
    # the last of the baseline: the FOG has its baseline and is in control
    assert f"fog {FOG} (KVH DSP-1760): in control ({history['stable']} runs; baseline: the " \
           f"first {BASELINE_RUNS} runs" \
        in _html_text(history["dirs"][-1])

    # bench control: every instrument with its status, the FOG flagged with the rule
    listing = cli("control", "--runs", str(runs))
    assert listing.returncode == 1, listing.stdout + listing.stderr
    fog_line = next(ln for ln in listing.stdout.splitlines() if FOG in ln)
    assert "OUT OF CONTROL, WE1 (Western Electric rule 1: one point beyond 3 sigma): " \
           "k at 50 deg/s" in fog_line
    counter_lines = [ln for ln in listing.stdout.splitlines() if OUTER["counter"] in ln]
    assert counter_lines, listing.stdout
    assert all("OUT OF CONTROL" not in ln for ln in counter_lines), counter_lines
    chart = cli("control", FOG, "--runs", str(runs))
    assert chart.returncode == 1
    assert f"baseline: the first {BASELINE_RUNS} runs" in chart.stdout and "WE1" in chart.stdout
    png = runs / f"control-{FOG}.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    # the certificate of run 9 says so; the next run's start warns; authorise refuses
    assert f"fog {FOG} (KVH DSP-1760): OUT OF CONTROL, WE1" in _html_text(shifted)
    stand = yaml.safe_load((shifted / "stand.yaml").read_text())
    warned: list[str] = []
    assert warn_at_start(parse_stand(stand), target(runs), warned.append) == warned
    assert any(FOG in w and "OUT OF CONTROL" in w and "WE1" in w for w in warned), warned
    refusals = assurance_refusals(shifted)
    assert len(refusals) == 1 and FOG in refusals[0] and "WE1" in refusals[0], refusals
    assert assurance_refusals(history["dirs"][-1]) == []   # run 8 rests on no signal
    lab = tmp_path / "lab.yaml"       # the shipped lab file, naming a register
    lab.write_text((CONFIGS / "lab.yaml").read_text())
    add_register(lab, tmp_path / "register")
    refused = authorise(shifted, "P. Petrov", lab)
    assert refused.returncode == 2, refused.stdout + refused.stderr
    assert FOG in refused.stderr and "WE1" in refused.stderr, refused.stderr
    assert not list((shifted / "issued").glob("*/certificate.pdf"))

    # a review with who and why lifts the refusal; the certificate then states it
    why = f"FOG {FOG} re-checked against the reference table; scale confirmed"
    bad = cli("control", FOG, "--runs", str(runs), "--review", "  ")
    assert bad.returncode == 2
    # a name typed after --by is not a reviewer: the register authenticates one (issue 42)
    for who, pw in (("Q. Manager", "not-her-password"), ("A. Ivanova", password("A. Ivanova"))):
        bad = cli_in(pw + "\n", "control", FOG, "--runs", str(runs), "--review", why, "--by",
                     who, "--lab", str(lab), "--password-stdin")
        assert bad.returncode == 2, bad.stdout
    assert assurance_refusals(shifted) != []
    rev = cli_in(password("Q. Manager") + "\n", "control", FOG, "--runs", str(runs),
                 "--review", why, "--by", "Q. Manager", "--lab", str(lab), "--password-stdin")
    assert rev.returncode == 0, rev.stdout + rev.stderr
    assert "review recorded: Q. Manager (account Q. Manager, authenticated)" in rev.stdout
    assert assurance_refusals(shifted) == []
    redo = cli("analyze", str(shifted), "--quiet")
    assert redo.returncode in (0, 1), redo.stderr[-2000:]
    text = _html_text(shifted)
    assert "reviewed by Q. Manager" in text and why in text
    doc = json.loads((shifted / "assurance.json").read_text())
    fog = next(i for i in doc["instruments"] if i["serial"] == FOG)
    assert fog["state"] == IN_CONTROL and fog["last_review"]["reviewer"].startswith(
        "Q. Manager (account Q. Manager, authenticated)")
    # with the review recorded, authorise issues; the issued certificate states the review
    issued = authorise(shifted, "P. Petrov", lab)
    assert issued.returncode == 0, issued.stdout + issued.stderr
    (html,) = (shifted / "issued").glob("*/certificate.html")
    text = re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", html.read_text(encoding="utf-8")))
    assert "reviewed by Q. Manager" in text and why in text


# -- the rules, each broken alone, on series built by hand ----------------------------------

T0 = dt.datetime(2026, 1, 1, tzinfo=dt.UTC)
BASE = [0.3, -0.5, 0.8, -0.2, 0.1, -0.9, 0.6, -0.2]      # mean 0, MR/1.128 = 0.8


def _points(values: list[float], u: float | None = 0.2) -> list[CheckPoint]:
    return [CheckPoint(f"uid{i}", f"run{i}", "T", T0 + dt.timedelta(days=i),
                       CheckRecord("S", "fog", None, "outer", "k", 50.0, v, u, "1"))
            for i, v in enumerate(values)]


def _rules(values: list[float]) -> list[str]:
    (series,) = charts(_points(values))
    return [g.rule for g in series.signals]


def test_the_limits_come_from_the_stated_baseline() -> None:
    (s,) = charts(_points(BASE + [0.0]))
    mr = statistics.fmean(abs(b - a) for a, b in zip(BASE, BASE[1:], strict=False))
    assert s.centre == pytest.approx(statistics.fmean(BASE))
    assert s.sigma == pytest.approx(mr / 1.128) and s.sigma_source.startswith("moving")
    assert s.baseline_text.startswith("baseline: the first 8 runs (run0 to run7")
    assert s.signals == ()


def test_each_western_electric_rule_and_the_ewma() -> None:
    sigma = charts(_points(BASE))[0].sigma
    assert sigma is not None
    assert _rules(BASE + [3.2 * sigma]) == ["WE1", "EWMA"]
    assert _rules(BASE + [2.2 * sigma, 0.0, 2.3 * sigma])[:1] == ["WE2"]
    assert "WE3" in _rules(BASE + [1.2 * sigma] * 4)
    assert _rules(BASE + [0.5 * sigma] * 8)[-1] in ("WE4", "EWMA")
    assert "WE4" in _rules(BASE + [0.5 * sigma] * 8)
    assert _rules(BASE + [-0.5 * sigma, 0.4 * sigma, -0.3 * sigma]) == []


def test_sigma_is_never_below_the_points_own_uncertainty() -> None:
    (s,) = charts(_points([1.0] * 8 + [1.3], u=0.2))   # identical baseline runs
    assert s.sigma == pytest.approx(0.1) and "U/2" in s.sigma_source
    assert [g.rule for g in s.signals] == ["WE1", "EWMA"]


def test_status_counts_reviews_and_history() -> None:
    short = status_of("S", "fog", None, _points(BASE[:5]), [])
    assert short.state == NOT_ENOUGH and "5 of 8 runs" in short.line
    pts = _points(BASE + [5.0])
    out = status_of("S", "fog", None, pts, [])
    assert out.state == OUT_OF_CONTROL and out.rule == "WE1"
    review = ReviewInfo("S", T0 + dt.timedelta(days=30), "QM", "checked", out.line,
                        pts[-1].date_utc)
    ok = status_of("S", "fog", None, pts, [review])
    assert ok.state == IN_CONTROL and "reviewed by QM" in ok.line and ok.reviewed_signals
    later = status_of("S", "fog", None, _points(BASE + [5.0, 5.0]), [review])
    assert later.state == OUT_OF_CONTROL       # a new signal after the review: refused again


def test_the_drift_keys_change_only_the_runs_they_name() -> None:
    stand = parse_stand({"stand": {"maker": "M", "model": "T", "serial": "S"},
                         "axes": {}, "sim": {"axes": {"outer": {"fog": {
                             "scale": 1.0003, "scale_step": {"from_run": 9, "rel": 2e-5},
                             "scale_ramp": {"from_run": 3, "rel_per_run": 1e-7}}}}}})
    assert stand.sim is not None

    def scale(run: int) -> float:
        return drifted(stand.sim, run)[0].axis("outer").truth.fog.scale  # type: ignore[arg-type]

    assert scale(1) == 1.0003
    assert scale(4) == pytest.approx(1.0003 * (1 + 2e-7))
    assert scale(9) == pytest.approx(1.0003 * (1 + 2e-5 + 7e-7))
    assert stand.sim.axis("outer").scale_step == (9, 2e-5)      # input untouched


@pytest.mark.timeout(300)
def test_the_station_shows_the_status_and_the_charts_in_a_real_browser(
        history: dict[str, Any]) -> None:
    from tests.test_station import TOKEN, _browser, _chromium, served_here

    found = _chromium()
    if found is None:
        unavailable("chromium and chromium-driver are not installed (Debian packages "
                    "`chromium chromium-driver`)")
        return
    from selenium.webdriver.common.by import By

    # the station's server in this process (the page is the subject, not its process)
    with served_here("--runs", str(history["runs"]), "--token", TOKEN) as port:
        # the station test's browser: headless, offline but for 127.0.0.1 (CHROMIUM_OFFLINE)
        driver = _browser(found, 1000)
        try:
            base = f"http://127.0.0.1:{port}"
            driver.get(f"{base}/records")
            rows = driver.find_element(By.ID, "instruments").text
            assert FOG in rows and OUTER["counter"] in rows
            driver.find_element(By.LINK_TEXT, FOG).click()
            status = driver.find_element(By.ID, "status").text
            assert "WE1" in status or "reviewed by" in status, status   # before/after review
            ok = driver.execute_script(
                "const i = document.getElementById('control'); return i.complete && i.naturalWidth")
            assert ok, "the control chart image did not load"
            assert f"baseline: the first {BASELINE_RUNS} runs" in driver.find_element(
                By.TAG_NAME, "main").text
        finally:
            driver.quit()


def test_a_review_may_restart_the_baseline() -> None:
    pts = _points(BASE + [5.0])
    review = ReviewInfo("S", T0 + dt.timedelta(days=30), "QM", "FOG repaired", None,
                        pts[-1].date_utc, new_baseline=True)
    s = status_of("S", "fog", None, _points(BASE + [5.0, 5.1, 4.9]), [review])
    assert s.state == NOT_ENOUGH and s.runs == 3 and "baseline restarted" in s.line
    later = _points(BASE + [5.0 + 0.1 * (i % 3) for i in range(BASELINE_RUNS + 1)])
    s = status_of("S", "fog", None, later, [review])
    assert s.state == IN_CONTROL and s.series[0].centre == pytest.approx(5.0875)
