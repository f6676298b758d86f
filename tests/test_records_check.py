"""`bench records check RUN...` (issue 57): what the lab database holds of a run equals
its run directory, and a difference is found and named: an event line deleted from
events.jsonl after delivery, one raw byte changed. A real short run on the twins, delivered
as it ran to a real PostgreSQL server (tests/pg_server.py)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import yaml

from tests.conftest import CONFIGS, bench, cli
from tests.pg_server import PgServer
from tests.test_fleet import _lab


@pytest.mark.timeout(400)
def test_records_check_finds_a_deleted_event_line_and_a_changed_raw_byte(
        pg: PgServer, tmp_path: Path) -> None:
    url = _lab(pg, "check_lab")
    proc = tmp_path / "short.yaml"
    proc.write_text(yaml.safe_dump({
        "procedure": "rate-ladder", "title": "checked", "turns": 2, "static_record_s": 5,
        "stand": str(CONFIGS / "stands" / "sim-two-axis.yaml"), "harmonics": 1,
        "axes": {"outer": {"rates_dps": [20]}}, "tolerance": {"rate_error": [{"rel": 1e-3}]},
    }))
    done = bench("run", str(proc), "--yes", "--out", str(tmp_path / "runs"), "--records", url)
    assert done.returncode == 0, done.stdout + done.stderr
    run = Path(done.stdout.strip().splitlines()[-1])
    lines = (run / "events.jsonl").read_bytes().splitlines(keepends=True)
    raw = json.loads((run / "result.json").read_text())["raw_files"]
    assert len(raw) == 3

    same = cli("records", "check", str(run), "--records", url)
    assert same.returncode == 0, same.stdout + same.stderr
    assert f"{run.name} (bench " in same.stdout
    assert f"equal: {len(lines)} event line(s), result, 3 raw file digest(s)" in same.stdout

    # a line deleted from the middle of the event log
    kept = run.parent / "kept-events.jsonl"
    shutil.copyfile(run / "events.jsonl", kept)
    gone = len(lines) // 2
    (run / "events.jsonl").write_bytes(b"".join(lines[:gone - 1] + lines[gone:]))
    deleted = cli("records", "check", str(run), "--records", url)
    assert deleted.returncode == 1, deleted.stdout
    assert f"{run.name} (bench " in deleted.stdout and "DIFFERS" in deleted.stdout
    kind = json.loads(lines[gone - 1])["event"]
    # one line deleted: one difference, named by its line number, not every line after it
    assert deleted.stdout.count("event line") == 1, deleted.stdout
    assert f"event line {gone} ({kind}): the lab database holds it, the run directory " \
           "does not (deleted?)" in deleted.stdout, deleted.stdout
    shutil.copyfile(kept, run / "events.jsonl")
    assert cli("records", "check", str(run), "--records", url).returncode == 0

    # one byte of the FOG's raw capture changed
    fog = next(run / f["path"] for f in raw if f["path"].endswith("fog.bin"))
    data = bytearray(fog.read_bytes())
    data[len(data) // 2] ^= 0x01
    fog.write_bytes(bytes(data))
    changed = cli("records", "check", str(run), "--records", url)
    assert changed.returncode == 1, changed.stdout
    rel = str(fog.relative_to(run))
    assert f"raw file {rel}: SHA-256 " in changed.stdout, changed.stdout
    assert changed.stdout.count("raw file ") == 1          # the other two are equal

    # a run the lab never received; and a file database is no lab server
    other = tmp_path / "other" / run.name
    shutil.copytree(run, other)
    meta = json.loads((other / "meta.json").read_text())
    (other / "meta.json").write_text(json.dumps({**meta, "run_uid": "0" * 32}))
    never = cli("records", "check", str(other), "--records", url)
    assert never.returncode == 1 and "never delivered" in never.stdout, never.stdout
    refused = cli("records", "check", str(run), "--records", f"sqlite:///{tmp_path}/r.db")
    assert refused.returncode == 2 and "is not a lab server" in refused.stderr
