"""One rule for the lab file (issue 57, items 1 and 2; docs/station.md "The lab file: one
rule"): docs/station.md's `bench run procedure.yaml --lab lab.yaml` runs, and its run goes
to the records the lab file names (the lab's PostgreSQL database, tests/pg_server.py), not
to a runs/records.sqlite; two lab files that differ refuse before anything is written; a
--records that would write elsewhere refuses; a resume keeps the run's own lab file.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import yaml

from tests.conftest import CONFIGS, ROOT, _env_without_lab
from tests.pg_server import PgServer
from tests.test_fleet import _lab

STAND = CONFIGS / "stands" / "sim-two-axis.yaml"


def _bench(*args: str, env: dict[str, str] | None = None, cwd: Path = ROOT
           ) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "bench", *args], cwd=cwd, text=True,
                          capture_output=True, timeout=300, stdin=subprocess.DEVNULL,
                          env={**_env_without_lab(), **(env or {})})


def _procedure(folder: Path, **extra: object) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    proc = folder / "procedure.yaml"
    proc.write_text(yaml.safe_dump({
        "procedure": "rate-ladder", "title": "lab rule", "stand": str(STAND), "turns": 2,
        "static_record_s": 5, "harmonics": 1, "prompts": False,
        "axes": {"outer": {"rates_dps": [20]}}, "tolerance": {"rate_error": [{"rel": 1e-3}]},
        **extra}))
    return proc


def test_two_lab_files_that_differ_refuse_before_anything_is_written(tmp_path: Path) -> None:
    a, b = tmp_path / "a.yaml", tmp_path / "b.yaml"
    a.write_text("laboratory: Lab A\n")
    b.write_text("laboratory: Lab B\n")
    same = tmp_path / "a-copy.yaml"
    same.write_text(a.read_text())
    out = tmp_path / "runs"
    named = _procedure(tmp_path / "p", certificate={"lab": str(b)})
    plain = _procedure(tmp_path / "q")
    for args, env, why in (
            ((str(plain), "--lab", str(a)), {"BENCH_LAB_SETTINGS": str(b)},
             "$BENCH_LAB_SETTINGS"),
            ((str(named), "--lab", str(a)), {}, "the procedure's certificate"),
            ((str(named),), {"BENCH_LAB_SETTINGS": str(a)}, "$BENCH_LAB_SETTINGS")):
        refused = _bench("run", *args, "--out", str(out), env=env)
        assert refused.returncode == 2, refused.stdout + refused.stderr
        assert "Not started: two lab files for one command" in refused.stderr
        assert why in refused.stderr, refused.stderr
    assert not out.exists()                        # nothing written, nothing moved
    # the same file named twice (or the same bytes) is one lab file
    both = _bench("plan", str(plain))       # plan reads no lab file: unaffected
    assert both.returncode == 0
    missing = _bench("run", str(plain), "--lab", str(tmp_path / "nope.yaml"), "--out", str(out))
    assert missing.returncode == 2 and "does not exist" in missing.stderr
    assert not out.exists()
    from bench.app import labfile
    assert labfile.choose([("--lab", a), ("env", same)]) == a


def test_the_docs_bench_run_with_lab_goes_to_the_lab_database(pg: PgServer,
                                                                tmp_path: Path) -> None:
    url = _lab(pg, "lab_rule")
    bench_dir = tmp_path / "bench"
    _procedure(bench_dir)
    (bench_dir / "lab.yaml").write_text(f"records: {url}\n")
    # the other bench's lab file in the environment would disagree: refused
    other = tmp_path / "other.yaml"
    elsewhere = tmp_path / "elsewhere.sqlite"
    other.write_text(f"records: sqlite:///{elsewhere}\n")
    clash = _bench("run", "procedure.yaml", "--lab", "lab.yaml", env={
        "BENCH_LAB_SETTINGS": str(other)}, cwd=bench_dir)
    assert clash.returncode == 2 and "two lab files" in clash.stderr, clash.stderr
    # --records that would write the run elsewhere than the lab's records: refused
    away = _bench("run", "procedure.yaml", "--lab", "lab.yaml", "--records",
                  f"sqlite:///{tmp_path}/mine.sqlite", cwd=bench_dir)
    assert away.returncode == 2 and "would write this run elsewhere" in away.stderr
    assert not (bench_dir / "runs").exists()

    # docs/station.md, word for word (run in the bench's folder)
    done = _bench("run", "procedure.yaml", "--lab", "lab.yaml", cwd=bench_dir)
    assert done.returncode == 0, done.stdout + done.stderr
    run = bench_dir / done.stdout.strip().splitlines()[-1]
    assert (run / "lab.yaml").read_text() == f"records: {url}\n"     # the run's copy
    assert not (bench_dir / "runs" / "records.sqlite").exists()
    from bench.app.records.extract import record_of
    from bench.app.records.store import Records
    from bench.app.station.fleet import FleetView
    with Records.open(url) as rec:
        assert [r.run_dir for r in rec.runs("SIM-0001")] == [run.name]
    shown = FleetView(url).benches()["benches"]
    assert [(b["run"], b["status"]) for b in shown] == [(run.name, "passed")]

    # a run's own command: its copy; a --lab that differs from it is refused
    resumed = _bench("run", "--resume", str(run), "--lab", str(other), cwd=bench_dir)
    assert resumed.returncode == 2 and "Not resumed: two lab files" in resumed.stderr
    again = _bench("analyze", str(run), cwd=bench_dir,
                   env={"BENCH_LAB_SETTINGS": str(other)})   # the copy wins over the env
    assert again.returncode == 0, again.stderr
    assert not elsewhere.exists()          # registered in the run's lab's records only
    check = _bench("records", "check", str(run), cwd=bench_dir)
    assert check.returncode == 0 and "equal" in check.stdout, check.stdout + check.stderr
    assert record_of(run).uid == next(iter(shown))["uid"]
