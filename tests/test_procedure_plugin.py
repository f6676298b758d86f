"""A procedure kind the project does not ship (tests/plugin_kind.py, `dwell`), registered
under its name as an entry point would register it, runs through the real CLI: validated,
planned, executed, analyzed, certified (HTML, PDF) and written as a valid DCC. Adding a
procedure needs no change outside its own code (README "How to add a procedure").
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest
from lxml import etree

from bench.app.cli import main
from bench.app.dcc.settings import ENV_LAB
from bench.app.dcc.validate import validate_dcc
from bench.core import registry

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
    rc = main(["run", str(proc), "--yes", "--out", str(out)])
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
