"""The drift-pulse result model (procedures/drift_pulse/result.py, msgspec Structs) and its
codec (codec.py): what the analysis builds is what result.json holds and what the readers
decode, every uncertainty twin a field of its own, and a malformed body is refused with the
key path that is wrong."""

from __future__ import annotations

import copy
import datetime as dt
import json
import math
from pathlib import Path

import pytest

from bench.app.certificate import write_certificate
from bench.core.journal import RunDir
from bench.report.certificate.sources import Sources
from procedures.drift_pulse import analysis as dp
from procedures.drift_pulse.codec import MalformedResult, decode, drift_of, encode
from procedures.drift_pulse.result import DriftFigures
from procedures.drift_pulse.sample import drift_figures, drift_pulse_result
from tests.drift_cycles import paper_truth, record_cycles

K_AS = {"x": 2.0, "y": 2.0, "z": 2.0}
STATED = {g: dp.StatedErrors(k_as_u_rel=1e-4, pulse_mismatch_max_rel=5e-6,
                             drift_random_walk_dph_per_rth=0.003) for g in "xyz"}


@pytest.fixture(scope="module")
def analysed() -> dp.DriftResult:
    recs, _ = record_cycles(paper_truth(), dp.SHAPES["rectangular"], cycles=4,
                            timing_cycles=2)
    return dp.analyze(recs, dp.SHAPES["rectangular"], K_AS, 70.0, STATED)


def _through_file(body: dict[str, object]) -> object:
    """As result.json carries it: through JSON."""
    return json.loads(json.dumps(body, allow_nan=False))


def test_the_analysis_result_survives_result_json(analysed: dp.DriftResult) -> None:
    figures = analysed.figures()
    body = encode(figures)
    back = decode(_through_file(body), DriftFigures)
    assert back == figures and encode(back) == body
    # every `_u` key beside its explicit twin, written by the model, not derived from names
    assert body["azimuth_u_deg"] == body["azimuth_U_deg"] == analysed.azimuth_u_deg
    ax = body["axes"]["x"]
    assert list(ax)[:3] == ["own_dph", "own_u_dph", "own_U_dph"]
    assert ax["cycles"][0]["offset_u_s"] == ax["cycles"][0]["offset_ustd_s"]
    x = back.axes["x"]
    # the values themselves, against the analysis that computed them
    assert x.own_dph == analysed.axes["x"].own_dph
    assert x.own_U_dph == analysed.axes["x"].own_u_dph
    assert x.own_budget is not None and x.own_budget.U == x.own_U_dph
    assert back.platform is not None and back.azimuth_budget is not None
    assert back.platform.azimuth_deg == analysed.azimuth_deg
    assert back.platform.azimuth_U_deg == back.azimuth_budget.U
    # each figure's k and nu_eff stated beside its U, from its budget (docs/method.md D1)
    assert body["azimuth_coverage_factor"] == back.azimuth_budget.k
    assert body["azimuth_dof_eff"] == back.azimuth_budget.dof_eff
    assert x.start_offset.cycles == len([c for c in x.cycles]) + 2   # + the timing cycles
    assert [p.table_deg for p in x.positions] == [0.0, 180.0]
    # the figure as a Quantity: value, U, and the k and nu_eff its budget computed U with
    own = x.own
    assert (own.value, own.U, own.unit) == (x.own_dph, x.own_U_dph, "deg/h")
    assert own.k == x.own_budget.k and own.dof == x.own_budget.dof_eff


def test_twins_that_differ_are_refused(analysed: dp.DriftResult) -> None:
    body = copy.deepcopy(encode(analysed.figures()))
    body["axes"]["y"]["own_U_dph"] = 1.0
    with pytest.raises(MalformedResult, match="differs from `own_u_dph`") as err:
        decode(body, DriftFigures)
    assert err.value.path == "drift.axes.y"


def test_the_checks_judge_the_own_drift_and_the_earth_rate(analysed: dp.DriftResult) -> None:
    checks = [encode(c) for c in analysed.checks(0.5, "simple")]
    assert [(c["axis"], c["quantity"]) for c in checks] == [
        ("x", "own_drift"), ("y", "own_drift"), ("x,y", "earth_horizontal_rate")]
    own = checks[0]
    assert own["value_dph"] == analysed.axes["x"].own_dph
    assert own["verdict"] == ("pass" if abs(own["value_dph"]) <= 0.5 else "fail")
    earth = checks[2]
    wh = 15.041 * math.cos(math.radians(70.0))
    assert earth["expected_dph"] == pytest.approx(wh, rel=1e-4)
    assert earth["verdict"] == ("pass" if analysed.earth_consistent else "fail")
    assert [c["quantity"] for c in (encode(x) for x in analysed.checks(None, "simple"))] \
        == ["earth_horizontal_rate"]                            # no tolerance, no own check


def test_the_sample_is_a_result_the_readers_accept() -> None:
    result = encode(drift_pulse_result())
    figures = drift_of(result)
    assert figures == drift_figures()
    assert figures.axes["x"].own_dph == 0.0523 and figures.axes["x"].own_U_dph == 0.0031
    assert figures.platform is not None and figures.platform.azimuth_deg == 80.02


def test_not_computed_is_a_result_without_figures() -> None:
    failed = DriftFigures.failed("each position needs at least two cycles")
    assert encode(failed) == {"axes": {}, "not_computed":
                              "each position needs at least two cycles"}
    back = decode(encode(failed), DriftFigures)
    assert back == failed and not back.axes and back.platform is None


@pytest.mark.parametrize(("damage", "path", "problem"), [
    (lambda d: d["axes"]["x"]["positions"][1].pop("mean_dph"),
     "drift.axes.x.positions[1].mean_dph", "missing"),
    (lambda d: d["axes"]["y"]["cycles"][3].update(drift_dph="0.1"),
     "drift.axes.y.cycles[3].drift_dph", "expected a number, got str"),
    (lambda d: d["axes"]["x"].update(start_offset=[]),
     "drift.axes.x.start_offset", "expected an object"),
    (lambda d: d["axes"]["x"]["start_offset"].update(detected=1),
     "drift.axes.x.start_offset.detected", "expected true or false"),
    (lambda d: d["axes"]["y"].update(positions={}),
     "drift.axes.y.positions", "expected a list"),
    (lambda d: d["budgets"][0].pop("terms"), "drift.budgets[0].terms", "missing"),
    (lambda d: d["budgets"][0]["correlations"][0].update(terms=[0, 99]),
     "drift.budgets[0]", "a correlation names a term outside"),
    (lambda d: d.pop("azimuth_u_deg"), "drift.azimuth_u_deg", "missing"),
    (lambda d: d.pop("latitude_deg"), "drift.latitude_deg", "missing"),
])
def test_a_malformed_body_is_refused_with_its_key_path(analysed: dp.DriftResult, damage,
                                                       path: str, problem: str) -> None:
    body = copy.deepcopy(encode(analysed.figures()))
    damage(body)
    with pytest.raises(MalformedResult, match=problem) as err:
        decode(body, DriftFigures)
    assert err.value.path == path
    assert str(err.value).startswith(f"result.json {path}: ")
    with pytest.raises(MalformedResult, match=r"^result.json drift: missing$"):
        drift_of({"procedure": "drift-pulse"})


def _certificate(tmp_path: Path, result: dict[str, object]) -> str:
    tmp_path.mkdir(parents=True, exist_ok=True)
    (tmp_path / "events.jsonl").touch()
    write_certificate(RunDir(tmp_path), Sources.load(result, tmp_path),
                      issued=dt.date(2025, 3, 6))
    return (tmp_path / "certificate.html").read_text(encoding="utf-8")


@pytest.mark.timeout(120)
def test_the_certificate_reads_the_typed_figures(tmp_path: Path) -> None:
    html = _certificate(tmp_path, encode(drift_pulse_result()))
    assert "+0.0523 ± 0.0031" in html and "80.020 ± 0.031 °" in html
    # the digitizer's offset, U expanded, as a deviation of the run (docs/method.md B)
    assert "Axis x: the digitizer&#39;s samples were +0.250 ± 0.010 ms off the pulse edges" \
        in html


@pytest.mark.timeout(120)
def test_a_result_without_figures_and_a_malformed_one(tmp_path: Path) -> None:
    failed = encode(drift_pulse_result()) | {"verdict": "incomplete", "drift": encode(DriftFigures.failed(
        "each position needs at least two cycles (for its scatter)"))}
    html = _certificate(tmp_path / "failed", failed)
    assert "Own and apparent drift per axis" not in html and "Site latitude" not in html
    broken = encode(drift_pulse_result())
    broken["drift"]["axes"]["x"].pop("own_dph")
    with pytest.raises(MalformedResult, match=r"^result.json drift.axes.x.own_dph: missing$"):
        _certificate(tmp_path / "broken", broken)
