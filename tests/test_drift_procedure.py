"""The drift-pulse procedure as the engine runs it: validate, plan, the paper's demo
end to end (checked against the platform twin's truth), and a fault during the turn.

Truth: the stand file's `sim:` block. The twin's own-drift random walk is rebuilt from
the same seed (its increments are drawn on the model grid from t = 0, whoever samples),
so the own drift is compared with its true mean over the measurement.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from bench.app.cli import main
from bench.app.commands import EXIT_ABORTED, EXIT_INVALID, EXIT_PASS, run_session
from bench.core.journal import RunDir
from bench.core.loader import load_config
from drivers.cia402 import FOLLOWING_ERROR
from sims.platform import GyroPlatform, PlatformTruth
from tests.conftest import CONFIGS, DemoRun, bench, journal_lines

DEMO = CONFIGS / "procedures" / "drift-demo.yaml"
STAND = CONFIGS / "stands" / "sim-gyro-platform.yaml"


def _write(tmp_path: Path, name: str, data: dict[str, Any]) -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _quick(tmp_path: Path, **over: Any) -> Path:
    """The demo, shortened: 1 s pulses, 2 timing and 4 measuring cycles per position."""
    d = yaml.safe_load(DEMO.read_text())
    d.update(stand=str(STAND), cycles=4, timing_cycles=2, settle_s=0.5, gap_s=0.1,
             pulse={**d["pulse"], "duration_s": 1, "points": 200}, **over)
    return _write(tmp_path, "quick.yaml", d)


@pytest.mark.timeout(60)
def test_validate_and_plan_work_for_drift_pulse_files(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    assert main(["validate", str(DEMO)]) == EXIT_PASS
    assert "valid drift-pulse procedure" in capsys.readouterr().out
    assert main(["plan", str(DEMO)]) == EXIT_PASS
    out = capsys.readouterr().out
    assert "platform to 180 deg (profile position)" in out
    assert "timing cycle 4/4 at 0 deg" in out and "cycle 10/10 at 180 deg" in out
    assert "Estimated bench time: 4 min" in out
    # every problem, by file, line and key, and nothing started
    d = yaml.safe_load(DEMO.read_text())
    d.update(stand=str(STAND), cycle=3, cycles=2)
    bad = _write(tmp_path, "bad.yaml", d)
    assert main(["validate", str(bad)]) == EXIT_INVALID
    err = capsys.readouterr().err
    assert f"{bad}:" in err and ": cycle: unknown key" in err
    assert "cycles: expected an integer >= 4" in err
    d = yaml.safe_load(DEMO.read_text())
    d.update(stand=str(STAND), positions_deg=[0, 360],
             pulse={**d["pulse"], "duration_s": 5.0003})
    bad = _write(tmp_path, "bad2.yaml", d)
    assert main(["validate", str(bad)]) == EXIT_INVALID
    err = capsys.readouterr().err
    assert "positions_deg: the positions must separate own and apparent drift" in err
    assert "pulse.duration_s: Tc = 5.0003 s is not a whole number of DMM intervals" in err
    s = yaml.safe_load(STAND.read_text())
    s["platform"]["gyros"]["y"]["awg_channel"] = 1
    s["platform"]["gyros"]["x"]["k_as_v_per_deg"] = 20.0
    stand = _write(tmp_path, "stand.yaml", s)
    d = yaml.safe_load(DEMO.read_text())
    d["stand"] = str(stand)
    proc = _write(tmp_path, "p.yaml", d)
    assert main(["plan", str(proc)]) == EXIT_INVALID
    err = capsys.readouterr().err
    assert "platform.gyros.y.awg_channel: channel 1 already drives gyro x" in err
    assert "gyro x: the pulse pair swings the angle sensor by 10 V" in err


def _truth_over(run_dir: Path) -> tuple[PlatformTruth, GyroPlatform, float, float]:
    stand = yaml.safe_load((run_dir / "stand.yaml").read_text())["sim"]
    truth = PlatformTruth.from_mapping(stand["platform"], seed=stand["seed"])
    cycles = [json.loads(x) for x in (run_dir / "events.jsonl").read_text().splitlines()]
    cycles = [e for e in cycles if e["event"] == "cycle" and not e["timing"]]
    return (truth, GyroPlatform(truth), cycles[0]["t_trigger_s"],
            cycles[-1]["t_trigger_s"] + 2 * cycles[-1]["tc_s"])


@pytest.mark.timeout(120)
def test_the_papers_case_70_80_end_to_end(drift_demo_run: DemoRun, tmp_path: Path) -> None:
    """`bench run` on the demo: own drift within U on each axis, mean relative drift error
    below 0.34 % and azimuth error below 2 arcmin (the paper's simulated figures, docs/method.md
    B), the azimuth within its U of the truth; `bench analyze` gives the same figures."""
    assert drift_demo_run.status == EXIT_PASS, drift_demo_run.stderr[-2000:]
    run_dir = drift_demo_run.copy_to(tmp_path / "runs")   # the session's run (conftest)
    result = json.loads((run_dir / "result.json").read_text())
    assert result["schema"] == "bench.result/1" and result["verdict"] == "pass"
    drift = result["drift"]
    truth, plat, t_from, t_to = _truth_over(run_dir)
    rel = []
    for g in ("x", "y"):
        ax = drift["axes"][g]
        own_true = plat.own_drift_dph(g, t_from, t_to)
        app_true = float(truth.apparent_dph(g))
        assert abs(ax["own_dph"] - own_true) <= ax["own_u_dph"], g
        assert abs(ax["apparent_dph"] - app_true) <= ax["apparent_u_dph"], g
        rel += [abs(ax["own_dph"] / own_true - 1), abs(ax["apparent_dph"] / app_true - 1)]
        assert len(ax["cycles"]) == 20 and ax["start_offset"]["cycles"] == 24
    assert np.mean(rel) < 0.0034
    assert abs(drift["azimuth_deg"] - 80.0) * 60 < 2.0
    assert abs(drift["azimuth_deg"] - 80.0) <= drift["azimuth_u_deg"]
    assert drift["earth_horizontal_consistent"] is True
    assert (run_dir / "certificate.pdf").exists()
    # the raw data alone give the same result
    a = bench("analyze", str(run_dir), timeout=60)
    assert a.returncode == EXIT_PASS, a.stderr[-2000:]
    again = json.loads((run_dir / "result.json").read_text())["drift"]
    for g in ("x", "y"):
        for k in ("own_dph", "own_u_dph", "apparent_dph", "apparent_u_dph"):
            assert again["axes"][g][k] == drift["axes"][g][k]
    assert again["azimuth_deg"] == drift["azimuth_deg"]


class _PastAngle:
    """Calls `action` at the first step of the co-simulation's clock (sims/clock.py
    SteppedClock) at which the turntable is past `deg`: mid-turn at a stand time fixed by
    the data, whatever the host's load (a wall-clock delay after the step's start may
    find the turn already over). A participant that only watches: no events of its own,
    always settled."""

    def __init__(self, table: Any, deg: float, action: Any) -> None:
        self.table, self.deg, self.action, self.at_s = table, deg, action, None

    def next_event_s(self, t_s: float) -> float:
        return math.inf

    def advance(self, t_s: float) -> None:
        if self.at_s is None and self.table.angle_deg > self.deg:
            self.at_s = t_s
            self.action()

    def settled(self, t_s: float, final: bool) -> bool:
        return True


@pytest.mark.timeout(120)
def test_a_fault_during_the_turn_stops_the_axis_exits_3_and_resumes(tmp_path: Path) -> None:
    cfg = load_config(_quick(tmp_path))
    run = RunDir.create(tmp_path / "runs", cfg.procedure_path, cfg.stand_path)
    seen: dict[str, Any] = {}

    def hook(sim: Any) -> None:
        seen["sim"] = sim
        assert getattr(sim.clock, "stepped", False), "the gyro stand runs on the co-simulation"
        seen["watch"] = _PastAngle(sim.stand.axes["turntable"], 20.0,
                                   lambda: sim.twins["turntable.drive"].inject(FOLLOWING_ERROR))
        sim.clock.join(seen["watch"])

    assert run_session(cfg, run, yes=True, on_sim_started=hook) == EXIT_ABORTED
    assert seen["watch"].at_s is not None
    events = journal_lines(run)
    abort = next(e for e in events if e["event"] == "abort")
    assert "0x8611" in abort["reason"] and "following error" in abort["reason"]
    assert next(e for e in events if e["event"] == "safe_stop")["ok"] is True
    table = seen["sim"].stand.axes["turntable"]
    assert table.rate_dps == 0.0 and 0.0 < table.angle_deg < 179.0   # stopped mid-turn
    assert not any(e["event"] == "turned" and e["position_deg"] == 180 for e in events)
    result = json.loads((run.path / "result.json").read_text())
    assert result["verdict"] == "incomplete"
    assert len(run.completed_units()) == 6                # the cycles at 0 deg are kept
    # --resume: the turn again, the cycles at 180 deg, then the full result
    assert run_session(cfg, run, yes=True, resume=True) == EXIT_PASS
    result = json.loads((run.path / "result.json").read_text())
    assert result["verdict"] == "pass" and result["sessions"] == 2
    for g in ("x", "y"):
        assert [p["cycles"] for p in result["drift"]["axes"][g]["positions"]] == [4, 4]
    assert abs(result["drift"]["azimuth_deg"] - 80.0) <= result["drift"]["azimuth_u_deg"]


@pytest.mark.timeout(60)
def test_pulses_that_never_reach_the_torque_sensor_abort_by_name(tmp_path: Path) -> None:
    cfg = load_config(_quick(tmp_path))
    run = RunDir.create(tmp_path / "runs", cfg.procedure_path, cfg.stand_path)

    def hook(sim: Any) -> None:
        sim.twins["gyro-rig"].awg.inject("no-output")     # a broken wire, for one burst

    assert run_session(cfg, run, yes=True, on_sim_started=hook) == EXIT_ABORTED
    abort = next(e for e in journal_lines(run) if e["event"] == "abort")
    assert "gyro x: the angle sensor shows a precession of" in abort["reason"]
    assert "generator channel 1" in abort["reason"]
    assert next(e for e in journal_lines(run) if e["event"] == "safe_stop")["ok"] is True


def test_sim_gyro_keys_are_the_twins_truth() -> None:
    """The stand file's `sim.platform.gyros.<gyro>` keys are the gyro twin's fields: a
    field added to sims/truth.py GyroTruth and not to the declaration would be refused."""
    import msgspec

    from procedures.drift_pulse.settings import SIM_GYRO_KEYS, SimGyro
    assert tuple(f.name for f in msgspec.structs.fields(SimGyro)) == SIM_GYRO_KEYS
