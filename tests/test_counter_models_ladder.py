"""Every counter model the project lists that can time a ladder runs the demo (issue 41).

The demo on a copy of configs/stands/sim-two-axis.yaml whose inner counter is another
model completes, and every figure is within its U of the twins' truth (the comparison of
tests/test_run_e2e.py). The 53230A is the demo itself (tests/test_run_e2e.py); the models
without time stamps (the 53220A, generic-scpi-period) are refused by `bench validate`
naming the missing capability (tests/test_validate_capabilities.py).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from drivers.counter_profiles import PROFILES
from tests.conftest import CONFIGS, bench
from tests.test_run_e2e import check_against_truth

STAND = CONFIGS / "stands" / "sim-two-axis.yaml"
DEMO = CONFIGS / "procedures" / "demo.yaml"
INNER = '"TCPIP0::127.0.0.1::5026::SOCKET", model: keysight-53230a'
#: the models the shipped demo does not already run, that time stamps
OTHERS = sorted(m for m, p in PROFILES.items() if p.supports_timestamps
                and m != "keysight-53230a")


def test_every_listed_model_is_either_run_here_or_refused_by_name() -> None:
    assert OTHERS == ["pendulum-cnt-91"]
    assert {m for m, p in PROFILES.items() if not p.supports_timestamps} == {
        "keysight-53220a", "generic-scpi-period"}


@pytest.mark.timeout(400)
@pytest.mark.parametrize("model", OTHERS)
def test_the_demo_with_its_inner_counter_another_model(model: str, tmp_path: Path) -> None:
    text = STAND.read_text()
    assert INNER in text
    (tmp_path / "stand.yaml").write_text(text.replace(INNER, INNER.replace(
        "keysight-53230a", model)))
    proc = tmp_path / "demo.yaml"
    proc.write_text(re.sub(r"(?m)^stand: .*$", "stand: stand.yaml", DEMO.read_text()))
    out = bench("run", str(proc), "--yes", "--out", str(tmp_path / "runs"), timeout=390)
    assert out.returncode in (0, 1), out.stderr[-3000:]
    run_dir = Path(out.stdout.strip().splitlines()[-1])
    result = json.loads((run_dir / "result.json").read_text())
    assert set(result["axes"]) == {"outer", "inner"}
    pattern = PROFILES[model].idn_pattern or ""
    assert re.search(pattern, str(result["instruments"]["inner"]["counter"]), re.I)
    check_against_truth(result)
