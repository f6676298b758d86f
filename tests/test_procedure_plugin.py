"""A procedure kind the project does not ship (the package tests/plugin_kind, `dwell`),
registered under its name as an entry point would register it, runs through the real CLI:
validated, planned, executed, analyzed, certified (HTML, PDF) and written as a valid DCC.
Adding a procedure needs no change outside its own package and its entry point (README
"How to add a procedure"), and mypy checks every part of it against the kind interface
(bench/kind.py): a part of the wrong type fails the type check.
"""

from __future__ import annotations

import csv
import json
import re
import shutil
from collections.abc import Callable
from pathlib import Path

import mypy.api
import pytest
from lxml import etree

from bench.app.cli import main
from bench.app.dcc.settings import ENV_LAB
from bench.app.dcc.validate import validate_dcc
from bench.core import registry
from tests.registers import lab_file, sqlite_register

NS = {"dcc": "https://ptb.de/dcc", "si": "https://ptb.de/si"}
DWELL_S = 1.0


@pytest.fixture
def register(monkeypatch: pytest.MonkeyPatch) -> Callable[[str], None]:
    """Register `tests.plugin_kind:<attr>` as the procedure kind `dwell` (what the line
    `dwell = "tests.plugin_kind:KIND"` under [project.entry-points."ratebench.procedures"]
    does for an installed package)."""
    monkeypatch.delenv(ENV_LAB, raising=False)

    def add(attr: str) -> None:
        found = {**registry._registered(), "dwell": f"tests.plugin_kind:{attr}"}
        monkeypatch.setattr(registry, "_registered", lambda: found)
    return add


def _run(tmp_path: Path) -> tuple[int, Path]:
    (tmp_path / "stand.yaml").write_text(
        "stand: {maker: Example Clocks, model: Bench Clock 1, serial: 'BC-0001'}\n")
    proc = tmp_path / "dwell.yaml"
    proc.write_text(f"procedure: dwell\ntitle: One second of dwell\nstand: stand.yaml\n"
                    f"dwell_s: {DWELL_S}\ntolerance_s: 0.5\nprompts: false\n"
                    "conditions: {temperature_c: '20 +/- 1'}\n")
    out = tmp_path / "runs"
    # a real stand (no `sim:` block) runs only under the lab's register (issue 54)
    lab = lab_file(tmp_path / "lab", sqlite_register(tmp_path / "register"))
    rc = main(["run", str(proc), "--yes", "--out", str(out), "--lab", str(lab)])
    runs = [p for p in out.iterdir() if p.is_dir()]
    assert len(runs) == 1, runs
    return rc, runs[0]


def _common(rc: int, run: Path) -> etree._Element:
    assert rc == 0
    result = json.loads((run / "result.json").read_text())
    assert result["procedure"] == "dwell"
    assert result["verdict"] == "pass"
    assert result["dwell"]["waited_s"] == pytest.approx(DWELL_S, abs=0.5)
    assert [c["quantity"] for c in result["checks"]] == ["dwell_time"]
    html = (run / "certificate.html").read_text()
    assert "Dwell results" in html and "dwell (a test plug-in)" in html
    assert (run / "certificate.pdf").read_bytes().startswith(b"%PDF")
    dcc = run / "certificate.dcc.xml"
    v = validate_dcc(dcc)
    assert v.valid, v.lines()[:3]
    return etree.parse(str(dcc)).getroot()


def test_a_plugin_kind_runs_through_the_cli_to_its_certificate_and_dcc(
        tmp_path: Path, register: Callable[[str], None]) -> None:
    register("KIND")
    assert "dwell" in registry.procedure_names()
    root = _common(*_run(tmp_path))
    q = root.find(".//dcc:measurementResult[@id='dwell']//dcc:quantity"
                  "[@refType='ratebench_dwellTime']", NS)
    assert q is not None
    assert float(q.findtext("si:real/si:value", None, NS)) == pytest.approx(DWELL_S, abs=0.5)
    assert q.findtext("si:real/si:unit", None, NS) == r"\second"
    assert q.findtext(".//dcc:metaData/dcc:conformity", None, NS) == "pass"
    item = root.find("dcc:administrativeData/dcc:items/dcc:item", NS)
    assert "Item calibrated: bench clock." in item.findtext("dcc:description/dcc:content",
                                                            None, NS)


def test_a_plugin_kind_without_a_dcc_part_still_gets_a_valid_dcc(
        tmp_path: Path, register: Callable[[str], None]) -> None:
    register("QUIET")
    root = _common(*_run(tmp_path))
    assert root.find(".//dcc:measurementResult[@id='noResults']", NS) is not None
    check = root.find(".//dcc:statements/dcc:statement[@id='check_1']", NS)
    assert check is not None and check.findtext("dcc:conformity", None, NS) == "pass"
    assert root.find(".//dcc:usedMethod[@id='methodDocument']", NS) is not None


# -- issue 25: a kind's figures reach every consumer through its declaration ---------------

SERIAL = "BC-0001"


def _sim_run(tmp_path: Path, dwell_s: float, capsys: pytest.CaptureFixture[str]
             ) -> tuple[Path, str]:
    """One dwell on the simulated bench's clock (the stand's `sim:` block), through the
    CLI; (its run directory, what `bench run` printed on standard output)."""
    (tmp_path / "stand.yaml").write_text(
        f"stand: {{maker: Example Clocks, model: Bench Clock 1, serial: '{SERIAL}'}}\n"
        "axes: {}\nsim: {seed: 3}\n")
    proc = tmp_path / f"dwell-{dwell_s:g}.yaml"
    proc.write_text(f"procedure: dwell\nstand: stand.yaml\ndwell_s: {dwell_s}\n"
                    "tolerance_s: 0.5\nprompts: false\n")
    capsys.readouterr()
    rc = main(["run", str(proc), "--yes", "--out", str(tmp_path / "runs")])
    out = capsys.readouterr().out
    assert rc == 0, out
    run = Path(out.strip().splitlines()[-1])          # the run directory is printed last
    assert json.loads((run / "result.json").read_text())["stand"]["simulated"] is True
    return run, out


def test_a_plugin_kinds_figures_reach_history_the_trend_plot_the_summary_and_station(
        tmp_path: Path, register: Callable[[str], None],
        capsys: pytest.CaptureFixture[str]) -> None:
    """Two dwells (1 s, then 2.5 s of simulated bench time) of one bench clock: the
    figures the kind declares (tests/plugin_kind FIGURES) are in the records, in
    `bench history`'s listing and CSV, in the points the trend plot draws (read back from
    the plotted lines), in the summary `bench run` prints at its end and in the station
    view's run figures and trend plot."""
    from bench.app.records import Records, target
    from bench.app.records.trend import trend_figure
    from bench.kind import declared_figures
    from tests.plugin_kind import FIGURES

    register("KIND")
    runs = [_sim_run(tmp_path, d, capsys) for d in (1.0, 2.5)]
    waited = [json.loads((r / "result.json").read_text())["dwell"]["waited_s"]
              for r, _ in runs]
    errors = [json.loads((r / "result.json").read_text())["dwell"]["error_s"]
              for r, _ in runs]
    # the twins' clock is exact: each dwell waited what it was asked, to rounding
    assert waited == pytest.approx([1.0, 2.5], abs=1e-9)

    # the run summary: the declared figures, printed by the certificate's rounding rule
    for (_, out), w in zip(runs, waited, strict=True):
        summary = out[out.index("\nResults\n"):]
        assert "Quantity" in summary and "Value ± U" in summary
        line = next(x for x in summary.splitlines() if "time waited, s" in x)
        assert f"+{w:.3f}" in line, line
        line = next(x for x in summary.splitlines() if "dwell error, ms" in x)
        assert line.rstrip().endswith("PASS"), line
        assert out.splitlines()[-2] == "verdict: PASS"

    # bench history: both runs, each figure listed with its value, every figure in its CSV
    csv_path, png = tmp_path / "h.csv", tmp_path / "h.png"
    rc = main(["history", SERIAL, "--runs", str(tmp_path / "runs"), "--csv", str(csv_path),
               "--plot", str(png)])
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "2 run(s)" in out
    assert [ln.split()[3] for ln in out.splitlines() if ln.endswith(("-dwell-1", "-dwell-2.5"))
            ] == ["dwell", "dwell"]
    listed = out[out.index("time waited, s:"):].splitlines()[1:3]
    assert [float(x.split()[1]) for x in listed] == pytest.approx(waited, abs=5e-4)
    assert "dwell error, ms:" in out
    rows = list(csv.DictReader(csv_path.open()))
    assert [float(r["value"]) for r in rows if r["quantity"] == "dwell_waited_s"] == waited
    got = [(float(r["value"]), r["verdict"], float(r["tolerance"]))
           for r in rows if r["quantity"] == "dwell_error_s"]
    assert got == [(e, "pass", 0.5) for e in errors]
    assert png.read_bytes()[:4] == b"\x89PNG"

    # the trend plot: one panel per trended figure; the plotted points are the runs' figures
    with Records.open(target(tmp_path / "runs").url) as rec:
        kinds = [r.kind for r in rec.runs(SERIAL)]
        points = rec.trend(SERIAL)
    assert kinds == ["dwell", "dwell"]
    assert declared_figures(kinds) == FIGURES
    fig = trend_figure(points, figures=declared_figures(kinds))
    assert fig is not None
    panels = {ax.get_ylabel(): ax for ax in fig.axes if ax.get_visible()}
    assert set(panels) == {"time waited, s", "dwell error, ms"}

    def plotted(label: str) -> list[float]:
        (line,) = [ln for ln in panels[label].get_lines() if ln.get_linestyle() == "-"
                   and len(ln.get_ydata()) == 2]
        return [float(y) for y in line.get_ydata()]

    assert plotted("time waited, s") == waited
    assert plotted("dwell error, ms") == pytest.approx([1e3 * e for e in errors], abs=1e-12)
    # the error's check tolerance (0.5 s) is drawn as its band, in the panel's unit
    assert any(ln.get_ydata()[0] == pytest.approx(500.0)
               for ln in panels["dwell error, ms"].get_lines() if ln.get_linestyle() == "--")

    # the station view, served over HTTP on this host (in this process, where the kind is
    # registered): each run's figures as the kind declares them, and the table's trend plot
    import threading
    import urllib.request

    from werkzeug.serving import make_server

    from bench.app.station.app import StationSettings, create_app

    app = create_app(StationSettings(runs=tmp_path / "runs", token="not-used-on-loopback"))
    http = make_server("127.0.0.1", 0, app, threaded=True)
    thread = threading.Thread(target=http.serve_forever, daemon=True)
    thread.start()
    try:
        base = f"http://127.0.0.1:{http.server_port}"
        for (run, _), w, e in zip(runs, waited, errors, strict=True):
            with urllib.request.urlopen(f"{base}/api/runs/{run.name}/figures") as r:
                shown = json.load(r)
            assert shown["procedure"] == "dwell"
            rows = {f["quantity"]: f for f in shown["figures"]}
            assert (rows["dwell_waited_s"]["value"], rows["dwell_waited_s"]["name"],
                    rows["dwell_waited_s"]["unit"]) == (w, "time waited", "s")
            assert (rows["dwell_error_s"]["value"], rows["dwell_error_s"]["verdict"]) == (
                e, "pass")
        with urllib.request.urlopen(f"{base}/api/records/{SERIAL}/trend.png") as r:
            assert r.status == 200 and r.read()[:4] == b"\x89PNG"
    finally:
        http.shutdown()
        thread.join(timeout=10)



# -- issue 61: mypy checks every part of a kind ------------------------------------------------

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "tests" / "plugin_kind"


def _mypy(*targets: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[int, str]:
    """mypy with the project's configuration and cache on `targets` alone (the bench's
    modules they import are read from the cache); (exit status, its report)."""
    monkeypatch.setenv("MYPYPATH", str(ROOT))
    out, err, status = mypy.api.run(
        ["--config-file", str(ROOT / "pyproject.toml"),
         "--cache-dir", str(ROOT / ".mypy_cache"), "--no-error-summary",
         *[str(t) for t in targets]])
    return status, out + err


def test_the_plugin_kind_passes_mypy(monkeypatch: pytest.MonkeyPatch) -> None:
    status, report = _mypy(PACKAGE, monkeypatch=monkeypatch)
    assert status == 0, report


#: (what is planted in a copy of the package's kind.py or report.py, what mypy must say)
PLANTED = {
    "a records part that is a certificate part": (
        "kind.py", "    records: DwellRecords = DwellRecords()",
        "    records: DwellCertificate = DwellCertificate()", "records: expected"),
    "a station part that is a DCC part": (
        "kind.py", "    station: StationParts = StationParts()",
        "    station: DwellDcc = DwellDcc()", "station: expected"),
    "a DCC part whose item is a string, not (words, axes)": (
        "report.py", "    def dcc_item(self, src: Sources) -> tuple[str, Sequence[str]]:\n"
                     '        return "bench clock", ()',
        "    def dcc_item(self, src: Sources) -> str:\n"
        '        return "bench clock"', "dcc_item"),
}


@pytest.mark.parametrize("plant", sorted(PLANTED))
def test_a_part_of_the_wrong_type_fails_mypy(plant: str, tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """A copy of the package with one part planted wrong: mypy fails where `KIND` is
    declared (or where the part's method is), naming the part."""
    module, right, wrong, said = PLANTED[plant]
    copy = tmp_path / "plugin_kind"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    # the copy's modules import each other, not the package they were copied from
    for path in copy.glob("*.py"):
        path.write_text(path.read_text().replace("tests.plugin_kind", "plugin_kind"))
    text = (copy / module).read_text()
    assert text.count(right) == 1, right
    (copy / module).write_text(text.replace(right, wrong))
    status, report = _mypy(copy, monkeypatch=monkeypatch)
    assert status == 1, report
    assert said in report and f"plugin_kind/{module}" in report, report


def test_the_kind_is_named_nowhere_outside_its_package_and_entry_point() -> None:
    """Adding the kind touched its package and the one line that registers it: the bench,
    the shipped kinds and the project's metadata do not name it."""
    named = [str(p.relative_to(ROOT)) for pkg in ("bench", "procedures", "drivers", "sims")
             for p in sorted((ROOT / pkg).rglob("*.py"))
             if "plugin_kind" in p.read_text(encoding="utf-8")
             or re.search(r"\bdwell", p.read_text(encoding="utf-8"))]
    assert named == []
    assert "dwell" not in (ROOT / "pyproject.toml").read_text()
