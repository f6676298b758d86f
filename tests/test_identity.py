"""The serial a stand states against the one the instrument reports (issue 41).

A swapped counter on a real bench must not land on another instrument's control chart:
a real stand whose instrument reports another serial is refused before anything moves
(tests/test_simserve.py drives that one against `bench sim`); on twins the mismatch is a
finding on the console and the certificate, and check values are filed under the serial
the instrument reported.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
import yaml

from bench.app.records.checks import checks_of
from bench.core.traceability import same_serial
from tests.conftest import bench
from tests.test_traceability import STAND, _mini


def test_one_serial_written_two_ways() -> None:
    assert same_serial("41001", "41001")
    assert same_serial("0xA029", "41001")          # 0x1018:4 is a number
    assert same_serial("my62000117", "MY62000117")
    assert not same_serial("MY59001234", "MY62000117")
    assert not same_serial("41001", "41002")


@pytest.mark.timeout(180)
def test_a_twin_reporting_another_serial_is_a_stated_finding(tmp_path: Path) -> None:
    text = STAND.read_text().replace(
        "counter: {resource: \"TCPIP0::127.0.0.1::5025::SOCKET\", model: keysight-53230a,",
        "counter: {resource: \"TCPIP0::127.0.0.1::5025::SOCKET\", model: keysight-53230a,\n"
        "              serial: MY59001234,", 1)
    assert "serial: MY59001234" in text
    proc = _mini(tmp_path, text)
    out = bench("run", str(proc), "--yes", "--out", str(tmp_path / "runs"), timeout=170)
    assert out.returncode in (0, 1), out.stderr[-3000:]
    said = ("axes.outer.counter.serial: the stand file states serial MY59001234, the "
            "instrument reports MY62000117 (*IDN?)")
    assert f"FINDING: {said}" in out.stderr, out.stderr[:3000]
    run_dir = Path(out.stdout.strip().splitlines()[-1])
    html = re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", (run_dir / "certificate.html")
                                      .read_text(encoding="utf-8")))
    assert ("Identity: axes.outer.counter.serial: the stand file states serial MY59001234, "
            "the instrument reported MY62000117 (*IDN?)") in html
    result = json.loads((run_dir / "result.json").read_text())
    stand = yaml.safe_load((tmp_path / "stand.yaml").read_text())
    counters = {c.serial for c in checks_of(run_dir, result, stand) if c.role == "counter"}
    assert counters == {"MY62000117"}, counters


def test_a_fog_answering_another_serial_to_its_is_query_is_a_mismatch() -> None:
    """The FOG's ?IS answer (KVH 1775 ICD 8.20) against the stand's fog.serial; a FOG not
    asked (configure: declare) keeps the stated serial and is no mismatch."""
    from bench.core.loader import load_config
    from bench.core.traceability import identity_mismatches
    from tests.conftest import CONFIGS

    stand = load_config(CONFIGS / "procedures" / "demo.yaml").stand_settings
    asked = {"outer": {"fog": "KVH DSP-1760, serial 170912345 (?IS); format kvh-a"}}
    [m] = identity_mismatches(stand, asked)
    assert m.text == ("axes.outer.fog.serial: the stand file states serial 1760-20231, the "
                      "instrument reports 170912345 (?IS)")
    same = {"outer": {"fog": "KVH DSP-1760, serial 1760-20231 (?IS); format kvh-a"}}
    assert identity_mismatches(stand, same) == []
    assert identity_mismatches(stand, {"outer": {"fog": "KVH DSP-1760; format kvh-a"}}) == []
