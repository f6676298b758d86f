"""A resume is a session of the same run (issue 57, item 3): the run's first session and
its first resume abort at a prompt nobody can answer (stdin is no terminal, no --yes);
the second resume completes. result.json and the certificate say the run completed, when
its last session ended, and list every session with its start, end and performer; the run
is a draft waiting for a signatory. A resume authenticates its performer as a new run does:
each session's performer is in the lab register's audit trail.
"""

from __future__ import annotations

import datetime as dt
import getpass
import html
import json
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

from tests.conftest import CONFIGS, ROOT, _env_without_lab
from tests.registers import lab_file, password, sqlite_register

STAND = CONFIGS / "stands" / "sim-two-axis.yaml"
PERFORMER = "A. Ivanova"


def _bench_piped(stdin: str, *args: str) -> subprocess.CompletedProcess[str]:
    """`bench ARGS` with `stdin` piped in: standard input is no terminal."""
    return subprocess.run([sys.executable, "-m", "bench", *args], cwd=ROOT, text=True,
                          input=stdin, capture_output=True, timeout=300,
                          env=_env_without_lab())


def _utc(stamp: str) -> dt.datetime:
    return dt.datetime.fromisoformat(stamp.replace("Z", "+00:00"))


@pytest.mark.timeout(600)
def test_a_run_resumed_twice_states_its_last_session_and_lists_every_session(
        tmp_path: Path) -> None:
    proc = _procedure(tmp_path)
    runs = tmp_path / "runs"
    run_dir = _aborted_twice(proc, runs, "")
    # the hint printed is the command that continues it: no --yes given, none suggested
    third = _bench_piped("", "run", "--resume", str(run_dir), "--yes")
    assert third.returncode == 0, third.stdout + third.stderr

    events = [json.loads(x) for x in (run_dir / "events.jsonl").read_text().splitlines()]
    by_session: dict[int, list[dict[str, Any]]] = {}
    for e in events:
        by_session.setdefault(e["session"], []).append(e)
    assert sorted(by_session) == [1, 2, 3]
    assert [e["event"] for e in by_session[1]].count("abort") == 1
    assert "completed" in [e["event"] for e in by_session[3]]

    result = json.loads((run_dir / "result.json").read_text())
    assert result["verdict"] == "pass"
    assert result["aborted"] is False and result["ended"] == "completed"
    assert result["sessions"] == 3
    completed = next(e for e in by_session[3] if e["event"] == "completed")
    assert result["dates"]["completed_utc"] == completed["utc"]
    # the last session ended after every earlier one (the old rule took the last abort)
    last_abort = [e["utc"] for e in events if e["event"] == "abort"][-1]
    assert _utc(result["dates"]["completed_utc"]) > _utc(last_abort)
    listed = result["run_sessions"]
    assert [s["session"] for s in listed] == [1, 2, 3]
    assert [s["ended"] for s in listed] == ["aborted", "aborted", "completed"]
    user = getpass.getuser()
    for s in listed:
        own = by_session[s["session"]]
        assert s["started_utc"] == own[0]["utc"]       # the session_start event
        assert s["performer"] is None and s["os_user"] == user    # no --operator given
        assert _utc(s["started_utc"]) <= _utc(s["ended_utc"])
    assert listed[0]["ended_utc"] == next(e["utc"] for e in by_session[1]
                                          if e["event"] == "abort")

    text = html.unescape(re.sub(r"<[^>]+>", " ", (run_dir / "certificate.html").read_text()))
    text = " ".join(text.split())
    ended = _utc(completed["utc"]).strftime("%Y-%m-%d %H:%M:%S UTC")
    assert f"Work ended {ended}" in text
    assert "(aborted)" not in text and "was aborted before every step" not in text
    assert "it ran in 3 sessions" in text
    for s in listed:
        assert (f"session {s['session']} from "
                f"{_utc(s['started_utc']).strftime('%Y-%m-%d %H:%M:%S UTC')}") in text
    assert text.count(f"performer not recorded (OS user {user})") == 3

    # a draft waiting for a signatory in the records the run registered in (a run on
    # the twins: in the simulated drafts, listed apart)
    from bench.app.records import Records
    with Records.open(f"sqlite:///{runs / 'records.sqlite'}") as rec:
        drafts = rec.drafts(simulated=True)
    assert [d[1] for d in drafts] == [run_dir.name]



def _procedure(tmp_path: Path, lab: Path | None = None) -> Path:
    proc = tmp_path / "short.yaml"
    proc.write_text(yaml.safe_dump({
        "procedure": "rate-ladder", "title": "resumed twice", "stand": str(STAND),
        "turns": 2, "static_record_s": 5, "harmonics": 1,
        "axes": {"outer": {"rates_dps": [20]}},
        "tolerance": {"rate_error": [{"rel": 1e-3}]},
        **({"certificate": {"lab": str(lab)}} if lab else {}),
    }))
    return proc


def _aborted_twice(proc: Path, runs: Path, stdin: str, *login: str) -> Path:
    """A run whose first session and first resume abort at the first prompt (standard
    input is no terminal, no --yes); its directory."""
    first = _bench_piped(stdin, "run", str(proc), "--out", str(runs), *login)
    assert first.returncode == 3, first.stdout + first.stderr
    assert "stdin is not a terminal" in first.stderr
    run_dir = Path(first.stdout.strip().splitlines()[-1])
    second = _bench_piped(stdin, "run", "--resume", str(run_dir), *login)
    assert second.returncode == 3, second.stdout + second.stderr
    assert "stdin is not a terminal" in second.stderr
    # the hint printed is the command that continues it as it was run (no --yes)
    assert f"Continue with: bench run --resume {run_dir}\n" in second.stdout
    return run_dir


@pytest.mark.timeout(300)
def test_each_session_authenticates_its_performer_in_the_register(tmp_path: Path) -> None:
    register = sqlite_register(tmp_path / "lab")
    proc = _procedure(tmp_path, lab_file(tmp_path / "lab", register))
    login = ("--operator", PERFORMER, "--password-stdin")
    run_dir = _aborted_twice(proc, tmp_path / "runs", f"{password(PERFORMER)}\n", *login)
    starts = [json.loads(x) for x in (run_dir / "events.jsonl").read_text().splitlines()]
    starts = [e for e in starts if e["event"] == "session_start"]
    assert [(e["session"], e["performer"]["account"]) for e in starts] == [
        (1, PERFORMER), (2, PERFORMER)]
    from bench.app.register import Register
    with Register.open(register, migrate=False) as reg:
        started = [r for r in reg.audit_rows() if r.action == "run started by"]
    assert [r.actor for r in started] == [PERFORMER, PERFORMER]
    # a wrong password refuses the resume before anything moves: no third session
    refused = _bench_piped("not-the-password-9\n", "run", "--resume", str(run_dir), *login)
    assert refused.returncode == 2, refused.stdout + refused.stderr
    assert "Not resumed: the lab register refuses" in refused.stderr
    assert not any(json.loads(x)["session"] == 3
                   for x in (run_dir / "events.jsonl").read_text().splitlines())


def test_session_endings_read_each_session_from_the_journal() -> None:
    """How each session ended, from the events alone: a session a later one followed
    without an end was killed; a `session_lost` line says so with the last event's time;
    an abort after the completion of the same session does not undo it; the last session
    without an end is not known yet (it may still run)."""
    from bench.core.events import decode_all
    from bench.core.journal import session_endings

    def ev(s: int, kind: str, utc: str, **more: object) -> dict[str, object]:
        return {"session": s, "event": kind, "utc": f"2026-01-01T00:{utc}+00:00", **more}

    events = [ev(1, "session_start", "00:00", pid=11, performer={"account": "A. Ivanova"}),
              ev(1, "step_start", "01:00"),                        # then killed
              ev(2, "session_start", "10:00", pid=12, os_user="op"),
              ev(2, "abort", "11:00"), ev(2, "exit", "11:01"),
              ev(3, "session_start", "20:00", pid=13),
              ev(3, "completed", "29:00"), ev(3, "abort", "29:10"), ev(3, "exit", "29:30"),
              ev(4, "session_start", "40:00", pid=14), ev(4, "step_start", "41:00")]
    got = session_endings(decode_all(events))
    assert [(x.session, x.ended, x.ended_utc[14:19] if x.ended_utc else None)
            for x in got] == [(1, "killed or crashed", "01:00"), (2, "aborted", "11:00"),
                              (3, "completed", "29:00"), (4, None, None)]
    assert [x.performer for x in got] == ["A. Ivanova", None, None, None]
    assert got[1].os_user == "op" and [x.pid for x in got] == [11, 12, 13, 14]
    lost = ev(4, "session_lost", "50:00", last_utc="2026-01-01T00:41:00+00:00")
    last = session_endings(decode_all([*events, lost]))[-1]
    assert (last.ended, last.ended_utc) == ("killed or crashed", "2026-01-01T00:41:00+00:00")
