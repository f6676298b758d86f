"""A run's numbers depend on its seed and files alone, never on machine load (issue 27).

Two runs of the demo on the twins' co-simulation clock (sims/clock.py SteppedClock): the
session's `demo_run` (tests/conftest.py), and the same command beside two busy processes
on this (2-core) machine:
every value in result.json is the same (what names the run, its dates and the pty or
port a twin happened to get aside), and so is every figure of the certificate. Before the
co-simulation three runs of seed 1 gave 15/5, 14/6 and 12/8 checks met/not assessed.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import CONFIGS, ControlBaseline, DemoRun, check_procedure, env_as_shipped

#: result.json keys that say when or where, not what was measured (`run_sessions`: each
#: session's start and end times and who ran it, issue 57)
_WHEN_WHERE = {"dates", "run_dir", "run_sessions"}
#: what differs between two runs in text: a certificate's number (from the run's time),
#: a date or time of day, the run directory's name, a twin's pty or TCP port
_VOLATILE = [
    (re.compile(r"DRAFT-\d{8}-[0-9A-F]{8}"), "DRAFT-<identifier>"),   # the run's own
    # the event log's length when the certificate was written (its lines carry wall times)
    (re.compile(r"(first|head -c) \d+"), r"\1 <bytes>"),
    (re.compile(r"\d{4}-\d\d-\d\d([ T]\d\d:\d\d(:\d\d(\.\d+)?)?( UTC|[+-]\d\d:\d\d)?)?"),
     "<date>"),
    (re.compile(r"\d{8}-\d{6}-demo"), "<run>"),
    (re.compile(r"\d{8}-\d{6}-drift-demo"), "<run>"),
    (re.compile(r"/dev/pts/\d+"), "<pty>"),
    (re.compile(r"127\.0\.0\.1::\d+"), "127.0.0.1::<port>"),
    # the files that journal the session's wall-clock dates: their size and digest
    (re.compile(r'(<td class="l">(?:meta\.json|events\.jsonl)</td>)<td class="r">[^<]+</td>'
                r'<td class="l">[0-9a-f]{64}</td>'), r"\1<size and digest>"),
]


def _normal(text: str) -> str:
    for pattern, repl in _VOLATILE:
        text = pattern.sub(repl, text)
    return text


def _strip(doc: Any) -> Any:
    if isinstance(doc, dict):
        return {k: _strip(v) for k, v in doc.items() if k not in _WHEN_WHERE}
    if isinstance(doc, list):
        return [_strip(v) for v in doc]
    if isinstance(doc, str):
        return _normal(doc)
    return doc


def _differences(a: Any, b: Any, where: str = "") -> Iterator[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            yield from _differences(a.get(k), b.get(k), f"{where}/{k}")
    elif isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            yield from _differences(x, y, f"{where}[{i}]")
    elif a != b:
        yield f"{where}: {a!r} != {b!r}"


@contextmanager
def _busy(n: int) -> Iterator[None]:
    """`n` processes spinning on a CPU each, for as long as the block runs."""
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]
    try:
        yield
    finally:
        for p in procs:
            p.kill()
        for p in procs:
            p.wait()


def _same(quiet: Path, loaded: Path) -> Any:
    """The quiet run's result.json stripped of when and where, once the loaded run's is
    shown equal to it."""
    a = _strip(json.loads((quiet / "result.json").read_text()))
    b = _strip(json.loads((loaded / "result.json").read_text()))
    diffs = list(_differences(a, b))
    assert not diffs, "\n".join(diffs[:30])
    return a


class _Started:
    """`bench run ARGS --yes --quiet` started in a subprocess, as an operator starts it, its
    output in files beside `log` (no pipe to fill while another run is waited for)."""

    def __init__(self, args: list[str], log: Path) -> None:
        self.out, self.err = log.with_suffix(".out"), log.with_suffix(".err")
        with open(self.out, "w") as out, open(self.err, "w") as err:
            self.p = subprocess.Popen([sys.executable, "-m", "bench", "run", *args, "--yes",
                                       "--quiet"], stdout=out, stderr=err, text=True,
                                      env=env_as_shipped())   # as the quiet runs were made

    def ended(self, timeout_s: float) -> tuple[int, str, str]:
        """Its exit status, standard output and standard error, once it has ended."""
        self.p.wait(timeout=timeout_s)
        return self.p.returncode, self.out.read_text(), self.err.read_text()

    def kill(self) -> None:
        if self.p.poll() is None:
            self.p.kill()
            self.p.wait()


def _demo_ended(run: _Started, out: Path) -> Path:
    """The run directory of a demo (the command of conftest's `demo_run` fixture, whose run
    is the quiet one), once it has passed."""
    status, stdout, stderr = run.ended(900)
    assert status == 0, stdout + stderr
    runs = [d for d in out.iterdir() if (d / "result.json").is_file()]
    assert len(runs) == 1, list(out.iterdir())
    return runs[0]


def _static_ended(run: _Started) -> Path:
    """The run directory of the check run of `_static_first`, once it has ended."""
    status, stdout, stderr = run.ended(600)
    assert status in (0, 1), stdout + stderr
    return Path(stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def loaded(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The loaded run of each test below, the three started at once beside two busy
    processes (on 2 cores): the demo, the drift demo and the control baseline's first check
    run (`_static_first`), each as an operator starts it. Each run meets the two busy
    processes and the other two runs besides, more load than either alone; and the busy
    processes spin once for the three (one run after the other, they spun two cores
    through each, a minute or more of CPU each in CI). The run directories by test: demo,
    drift, static."""
    folder = tmp_path_factory.mktemp("loaded")
    demo, drift = folder / "demo", folder / "drift"
    started: list[_Started] = []
    with _busy(2):
        try:
            for args, log in (([str(CONFIGS / "procedures" / "demo.yaml"), "--out", str(demo)],
                               "demo"),
                              ([str(CONFIGS / "procedures" / "drift-demo.yaml"), "--out",
                                str(drift)], "drift"),
                              (_static_first(folder / "static"), "static")):
                started.append(_Started(args, folder / log))
            return {"demo": _demo_ended(started[0], demo),
                    "drift": _demo_ended(started[1], drift),
                    "static": _static_ended(started[2])}
        finally:
            for run in started:      # a failed run leaves none of the others behind
                run.kill()


def _certificate_text(run: Path) -> str:
    html = (run / "certificate.html").read_text(encoding="utf-8")
    return _normal(html)


@pytest.mark.timeout(1200)      # the module's loaded runs (`loaded`) are made in its setup
def test_the_demo_gives_the_same_numbers_quiet_and_beside_two_busy_processes(
        demo_run: DemoRun, loaded: dict[str, Path]) -> None:
    assert demo_run.status == 0, demo_run.stderr[-3000:]
    quiet = demo_run.dir
    a = _same(quiet, loaded["demo"])
    # a check that can fail: the results carry figures, and the raw records are equal
    assert a["axes"]["outer"]["rates"], a["axes"]
    assert any(f["sha256"] for f in a["raw_files"])
    ca, cb = _certificate_text(quiet), _certificate_text(loaded["demo"])
    if ca != cb:
        la, lb = ca.splitlines(), cb.splitlines()
        lines = [f"line {i + 1}:\n  {x}\n  {y}"
                 for i, (x, y) in enumerate(zip(la, lb, strict=False)) if x != y]
        pytest.fail(f"certificates differ ({len(la)} and {len(lb)} lines):\n"
                    + "\n".join(lines[:10]))


def test_a_resumed_session_draws_its_own_noise_from_the_seed() -> None:
    """Each session's clock starts at stand time 0: with the stand's seed a --resume would
    replay session 1's noise sample for sample. Session 1 keeps the stand's seed; a later
    one gets a seed derived from (seed, session), the same on every machine."""
    from bench.core.config import SimSettings
    from bench.core.simbench import session_seed

    assert session_seed(SimSettings(seed=7)) == 7 == session_seed(SimSettings(seed=7, session=1))
    s2 = session_seed(SimSettings(seed=7, session=2))
    s3 = session_seed(SimSettings(seed=7, session=3))
    assert len({7, s2, s3}) == 3
    assert s2 == session_seed(SimSettings(seed=7, session=2))     # deterministic


@pytest.mark.timeout(900)
def test_the_drift_demo_gives_the_same_numbers_quiet_and_beside_two_busy_processes(
        drift_demo_run: DemoRun, loaded: dict[str, Path]) -> None:
    """The drift-pulse kind (docs/method.md B) on the co-simulation: the DMMs' and the
    generator's waits are on stand time (drivers/dmm.py), so the pulse triggers, the
    records' sample times and every reading are the same under any load."""
    assert drift_demo_run.status == 0, drift_demo_run.stderr[-3000:]
    quiet = drift_demo_run.dir
    a = _same(quiet, loaded["drift"])
    # a check that can fail: both gyros carry their cycles, and the raw records are equal
    for g in ("x", "y"):
        assert len(a["drift"]["axes"][g]["cycles"]) == 20, a["drift"]["axes"][g]
    assert {f["path"] for f in a["raw_files"]} >= {"raw/s1/x-dmm.jsonl", "raw/s1/awg.jsonl"}
    ca, cb = _certificate_text(quiet), _certificate_text(loaded["drift"])
    assert ca == cb, [(x, y) for x, y in zip(ca.splitlines(), cb.splitlines(), strict=False)
                      if x != y][:10]


def _static_first(folder: Path) -> list[str]:
    """A check run of the control charts' baseline (tests/conftest.py `check_procedure`,
    seed 1: one rate, its first step the FOG's static record, started the instant the
    instruments are open), the same files' bytes and names as the session's
    `control_baseline` run 1: the arguments of its `bench run` (`_start`)."""
    proc = check_procedure(folder, 1)
    return [str(proc), "--out", str(folder / "runs")]


@pytest.mark.timeout(900)
def test_a_static_record_at_the_start_begins_on_the_same_sample_under_load(
        control_baseline: ControlBaseline, loaded: dict[str, Path]) -> None:
    """The static record began at the newest FOG sample the reader held: the one due at
    that very instant was there on a quiet machine and not yet on a loaded one, so every
    later step moved by 1 ms (the control charts' drive settle time moved with it, and
    tests/test_control.py saw a false WE4 beside two busy processes). Now the clock alone
    places it (procedures/rate_ladder/kind.py `_do_static`). The quiet run is the
    session's first baseline run (made in the test process, by the console script's
    `main`), the loaded one the same files run by `bench` beside two busy processes."""
    quiet = control_baseline.run(1)
    _same(quiet, loaded["static"])
    drive = [(q.read_text(), lo.read_text()) for q, lo in
             zip(sorted(quiet.glob("raw/s*/outer-drive.jsonl")),
                 sorted(loaded["static"].glob("raw/s*/outer-drive.jsonl")), strict=True)]
    assert drive and all(x == y for x, y in drive)   # commands and settles, to the ms
    static = [json.loads(ln) for ln in (quiet / "events.jsonl").read_text().splitlines()
              if '"event":"static"' in ln.replace(" ", "")]
    # the FOG opens at the clock's 0.05 s (after the drive's identity read) and the record
    # starts with its first sample, the first after 0.05 s: sample 51, 5 s long
    assert [(round(e["t_s"] - 5.0, 9), e["fog_from"]) for e in static] == [(0.051, 51)], static
