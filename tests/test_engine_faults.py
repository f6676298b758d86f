"""Faults in the middle of a run: the engine stops every axis, keeps the data, exits 3.

The run goes through `run_session`, the function behind `bench run`, on the simulated
bench; faults are injected into the twins through their own fault hooks (an EMCY from
the drive, no trigger at the counter), so the drivers meet them as on hardware.
"""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any

import pytest
import yaml

from bench.app.commands import EXIT_ABORTED, run_session
from bench.core.journal import RunDir
from bench.core.loader import load_config
from drivers.cia402 import OVER_TEMPERATURE
from tests.conftest import CONFIGS, journal_lines, when_step_starts

STAND = CONFIGS / "stands" / "sim-two-axis.yaml"


def _procedure(tmp_path: Path) -> Path:
    proc = tmp_path / "p.yaml"
    proc.write_text(yaml.safe_dump({
        "procedure": "rate-ladder", "stand": str(STAND), "turns": 4, "static_record_s": 5,
        "harmonics": 1, "axes": {"outer": {"rates_dps": [100, 200]}},
    }))
    return proc


def _when_acquiring(run: RunDir, unit: str, action: Any) -> threading.Thread:
    """Call `action` once the engine has started acquiring in `unit`."""
    return when_step_starts(run, lambda e: e.get("action") == "acquire"
                            and e.get("unit") == unit, action)


def _drive_log(run: RunDir) -> list[dict[str, Any]]:
    path = run.path / "raw" / "s1" / "outer-drive.jsonl"
    return [json.loads(x) for x in path.read_text().splitlines()]


def _assert_stopped(run: RunDir) -> None:
    events = journal_lines(run)
    assert next(e for e in events if e["event"] == "safe_stop")["ok"] is True
    assert events[-1] == {**events[-1], "event": "exit", "status": EXIT_ABORTED}
    drive = _drive_log(run)
    assert abs([d for d in drive if d["kind"] == "feedback"][-1]["velocity_dps"]) < 1e-3
    states = [d["state"] for d in drive if d["kind"] == "state"]
    assert states[-1] in ("switch on disabled", "fault"), states[-5:]
    result = json.loads((run.path / "result.json").read_text())
    assert result["verdict"] == "incomplete"


@pytest.mark.timeout(120)
def test_a_drive_fault_mid_acquisition_stops_the_run(tmp_path: Path) -> None:
    cfg = load_config(_procedure(tmp_path))
    run = RunDir.create(tmp_path / "runs", cfg.procedure_path, cfg.stand_path)

    def hook(sim: Any) -> None:
        _when_acquiring(run, "outer/100dps",
                        lambda: sim.twins["outer.drive"].inject(OVER_TEMPERATURE))

    status = run_session(cfg, run, yes=True, on_sim_started=hook)
    assert status == EXIT_ABORTED
    abort = next(e for e in journal_lines(run) if e["event"] == "abort")
    assert "0x4310" in abort["reason"], abort["reason"]
    _assert_stopped(run)
    # the static record completed before the fault and is not lost
    assert run.completed_units() == ["outer/static"]


@pytest.mark.timeout(120)
def test_a_silent_counter_aborts_with_a_clear_error(tmp_path: Path) -> None:
    cfg = load_config(_procedure(tmp_path))
    run = RunDir.create(tmp_path / "runs", cfg.procedure_path, cfg.stand_path)

    def hook(sim: Any) -> None:
        sim.twins["outer.counter"].inject("no-trigger", count=5)

    status = run_session(cfg, run, yes=True, on_sim_started=hook)
    assert status == EXIT_ABORTED
    abort = next(e for e in journal_lines(run) if e["event"] == "abort")
    assert "counter" in abort["reason"].lower(), abort["reason"]
    _assert_stopped(run)
