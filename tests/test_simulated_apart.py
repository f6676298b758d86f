"""Runs on the twins are kept apart from real runs (issue 57, item 5): twins report the
serials a stand file states, so a lab's simulated rehearsals land on the real instruments'
serials. They must not enter a real instrument's control-chart baseline, nor the drafts
waiting for a signatory (they are listed apart).

The records are a real SQLite records database; the runs are registered as `bench run`
registers them (`Records.register`), eight simulated runs whose FOG scale is far off the
real one, then real runs.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

from bench.app.records import Records
from bench.app.records.checks import CheckRecord
from bench.app.records.control import IN_CONTROL, NOT_ENOUGH, OUT_OF_CONTROL, instrument_status
from bench.app.records.extract import RunRecord

FOG, TABLE = "FOG-REAL-1", "RT-REAL-7"
T0 = dt.datetime(2026, 3, 1, 8, 0)
REAL_K = [1.000300, 1.000302, 1.000299, 1.000301, 1.000298, 1.000300, 1.000303, 1.000299,
          1.000301]


def _run(n: int, k: float, simulated: bool, serial: str = FOG) -> RunRecord:
    when = T0 + dt.timedelta(days=n)
    return RunRecord(
        uid=f"{'sim' if simulated else 'real'}-{n}", serial=TABLE, maker="M", model="T",
        location=None, interval_days=365, kind="rate-ladder", title="check",
        run_dir=f"run-{'sim' if simulated else 'real'}-{n}", run_path=f"/runs/{n}",
        host="hall-1", procedure_name="p.yaml", procedure_sha256="0" * 64,
        stand_sha256="1" * 64, result_sha256=f"{n:064d}", created_utc=when,
        started_utc=when, completed_utc=when + dt.timedelta(hours=1), operator="op",
        verdict="pass", calibration_state=None, adjustment_note=None,
        certificate_number=None, simulated=simulated, sessions=1, aborted=False,
        bench_version="test",
        checks=(CheckRecord(serial, "fog", "KVH DSP-1760", "outer", "k", 50.0, k, 2e-6, "1"),))


def test_simulated_runs_stay_out_of_a_real_serials_baseline_and_drafts(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'records.sqlite'}"
    with Records.open(url) as rec:
        # eight rehearsals on the twins first: their k is 1.0003 * (1 + 5e-3), far off
        for n in range(8):
            rec.register(_run(n, 1.0053 + 1e-6 * n, simulated=True))
        for n, k in enumerate(REAL_K[:3]):
            rec.register(_run(10 + n, k, simulated=False))
        real = instrument_status(rec, FOG)
        assert real is not None
        # three real runs: not enough for a baseline (8); the simulated eight would make one
        assert (real.state, real.runs, real.simulated) == (NOT_ENOUGH, 3, False)
        assert "3 of 8 runs" in real.line and "SIMULATED" not in real.line
        # the simulated runs alone, asked for, are charted apart and say so
        sim = instrument_status(rec, FOG, simulated=True)
        assert sim is not None and (sim.state, sim.runs, sim.simulated) == (IN_CONTROL, 8, True)
        assert sim.line.endswith("SIMULATED runs only (kept apart from real runs)")

        for n, k in enumerate(REAL_K[3:], start=3):
            rec.register(_run(10 + n, k, simulated=False))
        real = instrument_status(rec, FOG)
        assert real is not None and real.runs == 9 and real.state == IN_CONTROL
        # the baseline is the first eight REAL runs: its centre is theirs, not the twins'
        (series,) = real.series
        assert abs(series.centre - sum(REAL_K[:8]) / 8) < 1e-12
        # a real run 5e-3 off is out of control against the real baseline
        rec.register(_run(30, 1.0053, simulated=False))
        assert instrument_status(rec, FOG).state == OUT_OF_CONTROL   # type: ignore[union-attr]

        drafts = [d[1] for d in rec.drafts()]
        simulated = [d[1] for d in rec.drafts(simulated=True)]
    assert drafts and all(d.startswith("run-real-") for d in drafts)
    assert len(drafts) == 10
    assert sorted(simulated) == sorted(f"run-sim-{n}" for n in range(8))
