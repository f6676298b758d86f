"""The fault campaign (issue 13) as a suite: faults x phases on the simulated bench.

Every cell runs `run_session` (the function behind `bench run`) on a short one-axis
ladder, injects one fault through the twins' own hooks (or a signal to this process)
once a step of the phase has started, and asserts: exit 3, an exit event, result.json
"incomplete", the axis at rest when the session ended, and, for the acquire phase,
a `--resume` that leaves the session's raw bytes unchanged and whose rate errors agree
with the stand's truth within U (k = 2; each figure held to the e2e hard limit 2.5 U).
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from bench.app.commands import EXIT_ABORTED, EXIT_PASS, run_session
from bench.core.events import SessionStarted
from bench.core.journal import RunDir
from bench.core.journal_codec import read_jsonl
from bench.core.loader import load_config
from drivers.cia402 import OVER_TEMPERATURE
from sims.fog_twin import Corrupt, Drop, Garbage, Stall
from sims.stand import AxisTruth
from tests.conftest import CONFIGS, JournalTail, bench_bg, journal_lines, when_step_starts

STAND = CONFIGS / "stands" / "sim-two-axis.yaml"
TRUTH_REL = AxisTruth.from_mapping(
    yaml.safe_load(STAND.read_text())["sim"]["axes"]["outer"]).mean_turn_rate_rel()
#: one figure against its truth: a k = 2 interval misses 5 % of the time, so a single
#: figure is held to the e2e suite's hard limit (tests/test_run_e2e.py), 2.5 U
HARD_LIMIT_U = 2.5


#: a top clock speed for the cells whose fault is noticed only after a real-time silence
#: (a lost drive heartbeat): at the paced clock's `max` this short ladder ends in about a
#: second of wall time, before the silence can count; at 30x the rest of the ladder lasts
#: 10 s or more of wall time after the fault, a loaded machine only slowing it further
SLOW_CLOCK = 30


def _procedure(folder: Path, clock_speed: float | None = None) -> Path:
    folder.mkdir(exist_ok=True)
    stand = STAND
    if clock_speed is not None:
        doc = yaml.safe_load(STAND.read_text())
        doc["sim"]["clock_speed"] = clock_speed
        stand = folder / "stand.yaml"
        stand.write_text(yaml.safe_dump(doc))
    proc = folder / "p.yaml"
    proc.write_text(yaml.safe_dump({
        "procedure": "rate-ladder", "stand": str(stand), "turns": 4, "sequence": "+-",
        "static_record_s": 3, "harmonics": 1, "prompts": False,
        "axes": {"outer": {"rates_dps": [20, 30]}},
    }))
    return proc


def _signal(sig: int) -> Callable[[Any], None]:
    return lambda sim: os.kill(os.getpid(), sig)


FAULTS: dict[str, Callable[[Any], None]] = {
    "drive-emcy": lambda sim: sim.twins["outer.drive"].inject(OVER_TEMPERATURE),
    "drive-heartbeat-lost": lambda sim: sim.twins["outer.drive"].silence_heartbeat(),
    "sigint": _signal(signal.SIGINT),
    "sigterm": _signal(signal.SIGTERM),
}
PHASES = ("static", "set_rate", "settle", "acquire")
#: an EMCY while the drive is still disabled (the static record) is journaled and cleared
#: by the enable that follows (CiA 402 fault reset): not an abort, so not a cell here
NOT_ABORTS = {("drive-emcy", "static")}
CELLS = [(f, ph) for f in sorted(FAULTS) for ph in PHASES if (f, ph) not in NOT_ABORTS]
#: cells whose run is also resumed (each resume is a whole run and a certificate: the
#: suite keeps to a few; RATEBENCH_RESUME_ALL=1 resumes every acquire-phase cell)
RESUMED = {("sigint", "acquire"), ("drive-heartbeat-lost", "acquire")}
RESUME_ALL = os.environ.get("RATEBENCH_RESUME_ALL") == "1"


def _hear_silence_sooner(monkeypatch: pytest.MonkeyPatch) -> None:
    """The controller notices a silent drive after at least the bench's real-time minimum
    (5 s); the paced clock would finish this short ladder first. Here the floor is 1 s
    (a test setting, not the bench's): the drive's own watchdog keeps its 5 s."""
    monkeypatch.setattr("drivers.axis.MIN_REAL_MARGIN_S", 1.0)


def _raw_hashes(run: RunDir, session: int) -> dict[str, str]:
    folder = run.path / "raw" / f"s{session}"
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.iterdir()) if p.is_file()}


def _session(cfg: Any, run: RunDir, inject: Callable[[Any], None] | None = None,
             phase: str | None = None, resume: bool = False) -> tuple[int, dict[str, Any]]:
    seen: dict[str, Any] = {}

    def hook(sim: Any) -> None:
        seen["sim"] = sim
        if inject is not None and phase == "start":
            inject(sim)     # in stand time, before the first sample: as the seed, not the load
        elif inject is not None:
            when_step_starts(run, lambda e: e.get("action") == phase and e.get("session")
                             == run.session, lambda: inject(sim), delay_s=0.02)

    status = run_session(cfg, run, yes=True, resume=resume, on_sim_started=hook)
    return status, seen


def _assert_aborted_cleanly(run: RunDir, status: int, seen: dict[str, Any]) -> None:
    assert status == EXIT_ABORTED
    events = journal_lines(run)
    mine = [e for e in events if e.get("session") == run.session]
    assert mine[-1]["event"] == "exit" and mine[-1]["status"] == EXIT_ABORTED, mine[-3:]
    assert any(e["event"] == "abort" for e in mine)
    result = json.loads((run.path / "result.json").read_text())
    assert result["verdict"] == "incomplete"
    axis = seen["sim"].stand.axes["outer"]
    t_end = seen["sim"].clock.now()
    assert axis.commanded_rate_at(t_end + 3600.0) == 0.0, "the axis was left turning"


@pytest.mark.timeout(240)
@pytest.mark.parametrize("fault,phase", CELLS)
def test_fault_in_phase_stops_keeps_and_resumes(fault: str, phase: str, tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    slow = fault == "drive-heartbeat-lost"
    if slow:
        _hear_silence_sooner(monkeypatch)
    cfg = load_config(_procedure(tmp_path, SLOW_CLOCK if slow else None))
    run = RunDir.create(tmp_path / "runs", cfg.procedure_path, cfg.stand_path)
    status, seen = _session(cfg, run, FAULTS[fault], phase)
    _assert_aborted_cleanly(run, status, seen)
    exit_event = [e for e in journal_lines(run) if e["event"] == "exit"][-1]
    if fault == "drive-heartbeat-lost":
        text = " ".join([exit_event["cause"] or "", *exit_event["later"]])
        assert "heartbeat" in text, exit_event
        assert "COULD NOT BE TOLD TO STOP" in text and "watchdog" in text, exit_event
        assert seen["sim"].twins["outer.drive"].watchdog_trips, "the drive's watchdog idle"
        _assert_the_first_cause_comes_first(capsys.readouterr().err, exit_event)
    if (fault, phase) not in RESUMED and not (RESUME_ALL and phase == "acquire"):
        return
    before = _raw_hashes(run, 1)
    again = RunDir(run.path)
    # the resume's subject is not a real-time silence: on the co-simulation clock
    status2, _ = _session(load_config(_procedure(tmp_path / "resume")) if slow else cfg,
                          again, resume=True)
    assert status2 == EXIT_PASS, [e for e in journal_lines(again) if e["event"] == "abort"]
    assert _raw_hashes(again, 1) == before          # the first session's bytes untouched
    result = json.loads((run.path / "result.json").read_text())
    # the run ends as its last session did (issue 57): the resume completed it
    assert result["sessions"] == 2 and result["aborted"] is False
    assert [s["ended"] for s in result["run_sessions"]] == ["aborted", "completed"]
    for r in result["axes"]["outer"]["rates"]:
        err, u = r["rate_error_rel"], r["rate_error_u_rel"]
        assert abs(err - TRUTH_REL) <= HARD_LIMIT_U * u, (r["set_rate_dps"], err, u)


@pytest.mark.timeout(120)
@pytest.mark.parametrize("fault", ["no-trigger", "garbage", "drop"])
def test_counter_fault_in_acquire(fault: str, tmp_path: Path) -> None:
    """The counter's own fault hooks (sims/scpi_server.py), hit on its data queries."""
    cfg = load_config(_procedure(tmp_path))
    run = RunDir.create(tmp_path / "runs", cfg.procedure_path, cfg.stand_path)
    status, seen = _session(cfg, run, lambda sim: sim.twins["outer.counter"].inject(
        fault, count=50), "acquire")
    _assert_aborted_cleanly(run, status, seen)


#: stand time of a FOG fault placed before the run: inside the +20 deg/s half's timed turns
#: (the acquire step starts ~7 s in, its lead-in turn lasts 18 s, its 4 timed turns 72 s)
FOG_FAULT_AT_S = 50.0


def _fog_fault(kind: str, at_s: float | None = None) -> Callable[[Any], None]:
    """A FOG fault 3 s (3000 frames) ahead of what the twin has encoded when the acquire
    step starts (a watcher thread: wall time), or at stand time `at_s` (placed at the
    sim's start: where it lands depends on the seed alone, not on how fast the watcher
    runs beside a simulation at ~300x real time, which a loaded CI once made it miss).
    Inside the half being timed (4 turns at 20 deg/s last 72 s). A lossy stall is kept
    under 128 frames: format A's 7-bit counter cannot see a loss of a whole multiple of
    128 (closing note of issue 13: a known limit, the kvh-b timestamp would)."""
    def inject(sim: Any) -> None:
        twin = sim.twins["outer.fog"]
        n = twin.next_sample + 3000 if at_s is None else int(at_s * twin.rate_hz)
        twin.inject({"corrupt": Corrupt(n, 50), "drop": Drop(n, 50), "garbage": Garbage(n, 500),
                     "stall": Stall(n, 30.0), "stall-lose": Stall(n, 0.1, lose=True),
                     "dead": Stall(n, 1e6, lose=True)}[kind])
    return inject


@pytest.mark.timeout(120)
@pytest.mark.parametrize("fault", ["corrupt", "drop", "garbage", "stall", "stall-lose"])
def test_a_fog_fault_in_acquire_is_counted_and_the_run_completes(
        fault: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Broken, lost, late or garbled frames are not a reason to stop a day's run: their
    samples are left out of the window (the integrals run on the FOG's time), the loss is
    said on the console and kept in result.json, and the truth is still recovered."""
    cfg = load_config(_procedure(tmp_path))
    run = RunDir.create(tmp_path / "runs", cfg.procedure_path, cfg.stand_path)
    status, _ = _session(cfg, run, _fog_fault(fault, at_s=FOG_FAULT_AT_S), "start")
    assert status == EXIT_PASS, capsys.readouterr().err
    rates = json.loads((run.path / "result.json").read_text())["axes"]["outer"]["rates"]
    for r in rates:
        assert abs(r["rate_error_rel"] - TRUTH_REL) <= HARD_LIMIT_U * r["rate_error_u_rel"], r
    lost = {r["set_rate_dps"]: r["fog_lost_frames"] for r in rates}
    if fault == "stall":                         # a lossless stall delivers every frame late
        assert sum(lost.values()) == 0, lost
    else:     # garbage: its decoy headers count as broken frames; no sample is lost
        assert lost[20.0] >= (1 if fault == "garbage" else 50), lost
        assert sum(lost.values()) == lost[20.0], lost
        assert "FOG frames lost or broken" in capsys.readouterr().err


@pytest.mark.timeout(180)
def test_a_dead_fog_in_acquire_aborts_cleanly_and_resumes(tmp_path: Path) -> None:
    cfg = load_config(_procedure(tmp_path))
    run = RunDir.create(tmp_path / "runs", cfg.procedure_path, cfg.stand_path)
    status, seen = _session(cfg, run, _fog_fault("dead"), "acquire")
    _assert_aborted_cleanly(run, status, seen)
    abort = [e for e in journal_lines(run) if e["event"] == "abort"][-1]
    assert abort["error"] == "FogTimeout" and "did not arrive" in abort["reason"], abort
    before = _raw_hashes(run, 1)
    again = RunDir(run.path)
    status2, _ = _session(cfg, again, resume=True)
    assert status2 == EXIT_PASS
    assert _raw_hashes(again, 1) == before


def _assert_the_first_cause_comes_first(err: str, exit_event: dict[str, Any]) -> None:
    """A failure while stopping is added beneath the first cause: the drive's heartbeat
    stops (the first cause); it then cannot be told to stop (a later error): the operator
    reads the cause first, the loud stop error beneath it, on the console and in the exit
    event. (Checked on every heartbeat cell of the matrix above: its own test, a run of
    the settle cell's, was the same fault in the same phase on the same ladder.)"""
    lines = err[err.index("Aborted: "):].splitlines()
    assert "no heartbeat from the drive" in lines[0], err
    loud = [ln for ln in lines[1:] if "COULD NOT BE TOLD TO STOP" in ln]
    assert loud and "watchdog (0x1016" in loud[0], err
    assert "no heartbeat from the drive" in exit_event["cause"]
    assert any("COULD NOT BE TOLD TO STOP" in x for x in exit_event["later"])


class _CtrlCOnCollect:
    """Sends SIGINT from its finaliser: the handler runs, and raises, inside `__del__`,
    where Python reports the exception as unraisable and goes on. Where a real Ctrl-C
    lands is chance; this makes it land in such a place on every run (a loaded suite run
    saw one land in SQLAlchemy's weakref callback while the certificate was written)."""

    def __del__(self) -> None:
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(1000):  # the handler runs here
            pass


def _lose_a_ctrl_c() -> None:
    _CtrlCOnCollect()          # collected at once: its finaliser runs in this thread


def _in_a_drive_tick_once_settling(run: RunDir, act: Callable[[], None]
                                   ) -> tuple[Callable[[Any], None], threading.Event,
                                              dict[str, Any]]:
    """A session hook that runs `act` once, inside the drive twin's tick in the main
    thread (the co-simulation steps the twins there), once the settle step has begun;
    and the event set when it ran, and what the hook saw (the simulated bench)."""
    armed, fired = threading.Event(), threading.Event()
    seen: dict[str, Any] = {}

    def hook(sim: Any) -> None:
        seen["sim"] = sim
        twin = sim.twins["outer.drive"]
        tick = twin._tick

        def tick_then_act(t_s: float) -> None:
            tick(t_s)
            if armed.is_set() and not fired.is_set() \
                    and threading.current_thread() is threading.main_thread():
                fired.set()
                act()

        twin._tick = tick_then_act
        when_step_starts(run, lambda e: e.get("action") == "settle", armed.set, delay_s=0.0)

    return hook, fired, seen


def _ctrl_c() -> None:
    os.kill(os.getpid(), signal.SIGINT)
    for _ in range(1000):  # the handler runs here, inside the twin's step
        pass


@pytest.mark.timeout(120)
@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
@pytest.mark.parametrize("lost", [False, True], ids=["raised", "lost-in-a-finaliser"])
def test_a_ctrl_c_landing_inside_a_twins_clock_step_still_stops_the_run(
        lost: bool, tmp_path: Path) -> None:
    """On the co-simulation clock the twins act in the thread that waits on the clock:
    the bench's main thread, where the SIGINT handler raises. A Ctrl-C that lands while
    the drive twin ticks must still end the run (exit 3, the cause "interrupted by
    SIGINT"), not be taken for a failed tick by the twin's catch-all and logged away
    (seen in a loaded suite run: the run completed with exit 0, and a second Ctrl-C only
    heard "the axes are being stopped first"). The signal is sent from inside the tick,
    so it lands there on every run, whatever the machine's load.

    `lost`: the handler's exception lost where it landed (a finaliser run by the tick,
    see `_CtrlCOnCollect`) is raised again at the next step boundary (SignalGuard.check):
    the run stops there, the same way, instead of exiting 0."""
    cfg = load_config(_procedure(tmp_path))
    run = RunDir.create(tmp_path / "runs", cfg.procedure_path, cfg.stand_path)

    hook, fired, seen = _in_a_drive_tick_once_settling(run, _lose_a_ctrl_c if lost
                                                       else _ctrl_c)
    status = run_session(cfg, run, yes=True, on_sim_started=hook)
    assert fired.is_set(), "no drive tick ran in the main thread after the settle began"
    exit_event = [e for e in journal_lines(run) if e["event"] == "exit"][-1]
    assert "interrupted by SIGINT" in (exit_event["cause"] or ""), exit_event
    _assert_aborted_cleanly(run, status, seen)   # exit 3, "incomplete", the axis at rest


def test_torn_journal_tail_resume_starts_on_a_fresh_line(tmp_path: Path) -> None:
    """A crash mid-write leaves half a line: the resume's session_start is not lost."""
    cfg = load_config(_procedure(tmp_path))
    run = RunDir.create(tmp_path / "runs", cfg.procedure_path, cfg.stand_path)
    log = run.path / "events.jsonl"
    log.write_text('{"utc":"x","session":1,"event":"session_start"}\n{"utc":"2026-11-2')
    run.begin_session()
    run.write(SessionStarted(resume=True))
    run.close()
    events = list(read_jsonl(log))
    assert [e["event"] for e in events] == ["session_start", "torn_tail", "session_start"]
    assert events[1]["bytes"] == len('{"utc":"2026-11-2')
    assert run.session == 2 and events[-1]["session"] == 2


@pytest.mark.timeout(240)
def test_sigkill_mid_acquire_then_resume(tmp_path: Path) -> None:
    """kill -9 (nothing of ours runs): the drive's watchdog stops the table; the run
    directory stays readable and --resume finishes it to the stand's truth within U."""
    proc = _procedure(tmp_path)
    child = bench_bg("run", str(proc), "--yes", "--out", str(tmp_path / "runs"))
    try:
        deadline = time.monotonic() + 120
        run_dir = None
        tail: JournalTail | None = None
        while time.monotonic() < deadline and child.poll() is None:
            found = [] if tail else list((tmp_path / "runs").glob("*/events.jsonl"))
            tail = tail or (JournalTail(found[0]) if found else None)
            if tail and any(e.get("action") == "acquire" and e.get("event") == "step_start"
                            for e in tail.read()):
                run_dir = tail.path.parent
                break
            time.sleep(0.05)
        assert run_dir is not None, child.stderr.read() if child.poll() is not None else ""
        time.sleep(0.2)
        child.kill()
    finally:
        child.wait(30)
    run = RunDir(run_dir)
    before = _raw_hashes(run, 1)
    cfg = load_config(run.procedure_file, run.stand_file)
    status, _ = _session(cfg, run, resume=True)
    assert status == EXIT_PASS
    assert _raw_hashes(run, 1) == before
    result = json.loads((run.path / "result.json").read_text())
    assert result["sessions"] == 2
    for r in result["axes"]["outer"]["rates"]:
        assert abs(r["rate_error_rel"] - TRUTH_REL) <= HARD_LIMIT_U * r["rate_error_u_rel"], r


@pytest.mark.timeout(120)
def test_ctrl_c_while_the_outputs_are_written_is_honoured(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The axes are stopped by then: Ctrl-C ends the writing (exit 3, an exit event, the
    way back via `bench analyze`) instead of being answered and ignored."""
    cfg = load_config(_procedure(tmp_path))
    run = RunDir.create(tmp_path / "runs", cfg.procedure_path, cfg.stand_path)

    def interrupt_while_writing() -> None:
        deadline = time.monotonic() + 100
        while time.monotonic() < deadline:
            if (run.path / "result.json").exists():   # written first, then the certificate
                os.kill(os.getpid(), signal.SIGINT)
                return
            time.sleep(0.01)

    threading.Thread(target=interrupt_while_writing, daemon=True).start()
    status = run_session(cfg, run, yes=True)
    assert status == EXIT_ABORTED
    err = capsys.readouterr().err
    assert f"bench analyze {run.path}" in err, err
    assert "being stopped first" not in err
    last = journal_lines(run)[-1]
    assert last["event"] == "exit" and last["status"] == EXIT_ABORTED


@pytest.mark.timeout(120)
@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
def test_a_ctrl_c_lost_in_a_finaliser_while_writing_still_ends_the_run(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The writing's Ctrl-C lost where it landed is raised again once the outputs are
    written (SignalGuard.check): exit 3 and the way back, not exit 0."""
    from bench.app import session

    cfg = load_config(_procedure(tmp_path))
    run = RunDir.create(tmp_path / "runs", cfg.procedure_path, cfg.stand_path)
    write_dcc = session.write_run_dcc
    lost = threading.Event()

    def lose_then_write(*args: Any, **kwargs: Any) -> bool:
        lost.set()
        _lose_a_ctrl_c()
        return write_dcc(*args, **kwargs)

    monkeypatch.setattr(session, "write_run_dcc", lose_then_write)
    status = run_session(cfg, run, yes=True)
    assert lost.is_set()
    err = capsys.readouterr().err
    assert status == EXIT_ABORTED, err
    assert f"bench analyze {run.path}" in err, err
    last = journal_lines(run)[-1]
    assert last["event"] == "exit" and last["status"] == EXIT_ABORTED, last
    assert last["cause"] == "interrupted while writing the outputs", last


def _fill(folder: Path) -> None:
    """Another process fills the disk: write until the file system says ENOSPC."""
    block = b"\0" * (1 << 20)
    with open(folder / "filler", "wb") as f:
        try:
            while True:
                f.write(block)
                f.flush()
        except OSError:
            pass


@pytest.mark.timeout(180)
def test_full_disk_mid_acquire_names_the_file_and_resumes(
        tmp_path: Path, small_disk: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = load_config(_procedure(tmp_path))
    run = RunDir.create(small_disk, cfg.procedure_path, cfg.stand_path)
    status, seen = _session(cfg, run, lambda sim: _fill(small_disk), "acquire")
    err = capsys.readouterr().err
    assert status == EXIT_ABORTED, err
    assert "Traceback" not in err
    assert "No space left on device" in err and f"cannot write {run.path}" in err, err
    axis = seen["sim"].stand.axes["outer"]
    assert axis.commanded_rate_at(seen["sim"].clock.now() + 3600.0) == 0.0
    before = _raw_hashes(run, 1)
    (small_disk / "filler").unlink()                    # the operator frees space
    again = RunDir(run.path)
    status2, _ = _session(cfg, again, resume=True)
    assert status2 == EXIT_PASS, capsys.readouterr().err
    assert _raw_hashes(again, 1) == before
    starts = [e for e in journal_lines(again) if e["event"] == "session_start"]
    assert [e["session"] for e in starts] == [1, 2]     # the journal stayed readable
