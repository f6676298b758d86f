"""A bench killed mid-run (issue 57, item 4): SILENT on the lab page means a live bench
process that stopped talking; once the process is gone, the bench's next `bench records
sync` or `bench run` journals "ended: killed or crashed" in the run's own event log and
delivers it, and the lab page (headless chromium on `bench serve`) shows the run ended at
its last step, not silent.

The run is the recorded one-pair ladder (tests/data/fleet/ladder-run) cut after its pair,
its session's process a stand-in whose pid the test controls; a real PostgreSQL server.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import sqlalchemy as sa
import yaml

from bench.app.records import schema as s
from bench.app.records.store import Records
from tests.conftest import CONFIGS, cli
from tests.pg_server import PgServer
from tests.registers import cli_in
from tests.test_fleet import RECORDED, _lab, _recorded_run, _rows

CUT = 33          # the recorded event log to the pair's first look, no exit


def _stand_in() -> subprocess.Popen[bytes]:
    """A live process whose command line names a bench, as a bench's does."""
    return subprocess.Popen([sys.executable, "-c", "import time; time.sleep(300)",
                             "bench-stand-in"])


def _run_of(runs: Path, name: str, pid: int) -> Path:
    lines = (RECORDED / "events.jsonl").read_text().splitlines(keepends=True)[:CUT]
    start = json.loads(lines[0])
    assert start["event"] == "session_start"
    lines[0] = json.dumps({**start, "pid": pid}, separators=(",", ":")) + "\n"
    return _recorded_run(runs, name, "".join(lines).encode())


def _last_step(run: Path) -> str:
    events = [json.loads(x) for x in (run / "events.jsonl").read_text().splitlines()[:CUT]]
    return str([e for e in events if e["event"] == "step_start"][-1]["describe"])


def test_a_killed_bench_tells_the_lab_at_its_next_sync_and_start(pg: PgServer,
                                                                  tmp_path: Path) -> None:
    from tests.test_station import _browser, _chromium, _wait, served_here

    found = _chromium()
    if found is None:
        from tests.conftest import unavailable
        unavailable("chromium and chromium-driver are not installed (.ci/run installs them)")
    url = _lab(pg, "lost_bench_lab")
    runs = tmp_path / "runs"
    proc = _stand_in()
    try:
        run = _run_of(runs, "20261127-204740-one", proc.pid)
        # the process lives: the sync delivers the run as running, journals nothing
        first = cli("records", "sync", "--runs", str(runs), "--records", url)
        assert first.returncode == 0, first.stderr
        assert "killed or crashed" not in first.stdout
        assert len((run / "events.jsonl").read_text().splitlines()) == CUT
        # not heard for 60 s while its process lives: SILENT
        with Records.open(url) as rec, rec.engine.begin() as conn:
            conn.execute(sa.update(s.bench_runs).values(
                received_utc=sa.func.timezone("UTC", sa.func.now())
                - sa.text("interval '60 s'")))
        from bench.app.station.fleet import FleetView
        (shown,) = FleetView(url).benches()["benches"]
        assert shown["status"] == "silent"
    finally:
        proc.kill()
        proc.wait()
    # the process is gone (kill -9): the next sync says so, journals it, delivers it
    second = cli("records", "sync", "--runs", str(runs), "--records", url)
    assert second.returncode == 0, second.stderr
    assert f"{run.name}: ended: killed or crashed (session 1: its bench process " \
           f"{proc.pid} is gone" in second.stdout, second.stdout
    lost = json.loads((run / "events.jsonl").read_text().splitlines()[-1])
    assert (lost["event"], lost["session"], lost["ended"], lost["pid"]) == (
        "session_lost", 1, "killed or crashed", proc.pid)
    assert lost["last_step"] == _last_step(run) and lost["found_by"] == "bench records sync"
    assert _rows(url, run.name)[-1] == (CUT + 1, lost)
    again = cli("records", "sync", "--runs", str(runs), "--records", url)
    assert "killed or crashed" not in again.stdout and "0 new event(s)" in again.stdout

    # the station's server in this process (its page is the subject, not its process)
    with served_here("--runs", str(tmp_path / "station"), "--records", url) as port:
        driver = _browser(found, height=1000)
        try:
            driver.get(f"http://127.0.0.1:{port}/")

            def shown() -> list[dict[str, object]]:
                return driver.execute_script(
                    "return window.fleet && window.fleet.benches") or []
            _wait(lambda: bool(shown()), 60, "the lab page's first update")
            (b,) = shown()
            assert b["status"] == "stopped", b
            table = str(driver.execute_script(
                "return document.getElementById('fleet-table').innerText"))
            assert "SILENT" not in table, table
            # ended, with its last step (the tenth of ten, done before the kill)
            assert _last_step(run) == "ramp to zero, disable"
            assert "Stopped after step 10 of 10 (outer stop - ramp to zero, disable): ended: " \
                   "killed or crashed" in table, table
            driver.get(f"http://127.0.0.1:{port}/bench/{b['bench']}/{b['uid']}")
            page = driver.find_element("tag name", "main").text
            assert "ended: killed or crashed" in page and "SILENT" not in page, page
        finally:
            driver.quit()

    # a bench's next start does the same for a run killed since: journaled, delivered
    proc = _stand_in()
    proc.kill()
    proc.wait()
    other = _run_of(runs, "20261127-204741-two", proc.pid)
    procedure = tmp_path / "next.yaml"
    procedure.write_text(yaml.safe_dump({
        "procedure": "rate-ladder", "title": "next", "turns": 2, "static_record_s": 5,
        "stand": str(CONFIGS / "stands" / "sim-two-axis.yaml"), "harmonics": 1,
        "axes": {"outer": {"rates_dps": [20]}}, "tolerance": {"rate_error": [{"rel": 1e-3}]},
    }))
    # standard input is no terminal (empty) and no --yes: the new run aborts at its first
    # prompt (the console script's `main` in this process: the bench's start, not an
    # interpreter's, is the subject)
    nxt = cli_in("", "run", str(procedure), "--out", str(runs), "--records", url)
    assert nxt.returncode == 3, nxt.stdout + nxt.stderr
    assert f"found: {other.name}: ended: killed or crashed" in nxt.stderr + nxt.stdout
    body = _rows(url, other.name)[-1][1]
    assert body["event"] == "session_lost" and body["found_by"] == "bench run"
