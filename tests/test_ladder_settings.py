"""A per-axis `turns` is what the plan, the result and the certificate all say (issue 12).

Before the settings were parsed once (procedures/rate_ladder/settings.py LadderSettings),
the plan applied the per-axis value while the analysis's Method record read the
top-level one: a certificate said "Turns 2" for an axis that ran 3.
"""

from __future__ import annotations

import html
import json
import re
from pathlib import Path

import pytest
import yaml

from bench.commands import EXIT_PASS, run_session
from bench.journal import RunDir
from bench.loader import load_config
from bench.registry import procedure_kind
from procedures.rate_ladder.settings import LadderSettings
from tests.conftest import CONFIGS

STAND = CONFIGS / "stands" / "sim-two-axis.yaml"


def _procedure(folder: Path, **top: object) -> Path:
    proc = folder / "p.yaml"
    proc.write_text(yaml.safe_dump({
        "procedure": "rate-ladder", "stand": str(STAND), "sequence": "+-",
        "static_record_s": 2, "harmonics": 1, "prompts": False, **top,
        "axes": {"outer": {"rates_dps": [60], "turns": 3},
                 "inner": {"rates_dps": [60]}},
    }, sort_keys=False))
    return proc


def test_settings_take_the_axis_value_and_the_top_level_default(tmp_path: Path) -> None:
    cfg = load_config(_procedure(tmp_path, turns=2))
    ladder = LadderSettings.from_config(cfg)
    assert {a: s.turns for a, s in ladder.axes.items()} == {"outer": 3, "inner": 2}
    assert ladder.method()["turns"] == "outer 3, inner 2"
    plan = procedure_kind(cfg.kind).build_plan(cfg)
    timed = {(st.axis, st.params["half"]): st.params["turns"]
             for st in plan.steps if st.action == "acquire"}
    assert timed == {("outer", 0): 3, ("outer", 1): 3, ("inner", 0): 2, ("inner", 1): 2}


def test_a_file_without_turns_takes_the_one_default(tmp_path: Path) -> None:
    cfg = load_config(_procedure(tmp_path))
    ladder = LadderSettings.from_config(cfg)
    assert ladder.turns == 5 and ladder.axes["inner"].turns == 5    # DEFAULTS["turns"]
    assert ladder.axes["outer"].turns == 3


@pytest.mark.timeout(300)
def test_per_axis_turns_in_result_and_certificate(tmp_path: Path) -> None:
    cfg = load_config(_procedure(tmp_path, turns=2))
    run = RunDir.create(tmp_path / "runs", cfg.procedure_path, cfg.stand_path)
    assert run_session(cfg, run, yes=True) == EXIT_PASS
    result = json.loads((run.path / "result.json").read_text())
    assert {a: {r["turns"] for r in v["rates"]} for a, v in result["axes"].items()} \
        == {"outer": {3}, "inner": {2}}
    assert {a: [len(r["counter_rate_dps"]) for r in v["rates"]]
            for a, v in result["axes"].items()} == {"outer": [3, 3], "inner": [2, 2]}
    assert result["method"]["turns_per_axis"] == {"outer": 3, "inner": 2}
    text = html.unescape(re.sub(r"<[^>]+>", " ", (run.path / "certificate.html").read_text()))
    text = re.sub(r"\s+", " ", text)
    assert "Turns outer 3, inner 2" in text, re.findall(r"Turns [^A-Z]{0,40}", text)
