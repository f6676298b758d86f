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
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import CONFIGS, ControlBaseline, DemoRun, check_procedure

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


def _quiet_and_loaded(run: Callable[[Path], Path], tmp_path: Path,
                      quiet: Path | None = None) -> tuple[Path, Path, Any]:
    """`run` once quiet (or `quiet`, the same command's run directory from a session
    fixture) and once beside two busy processes; both run directories, and the quiet
    result.json stripped of when and where, once the loaded one is shown equal."""
    quiet = quiet or run(tmp_path / "quiet")
    with _busy(2):
        loaded = run(tmp_path / "loaded")
    a = _strip(json.loads((quiet / "result.json").read_text()))
    b = _strip(json.loads((loaded / "result.json").read_text()))
    diffs = list(_differences(a, b))
    assert not diffs, "\n".join(diffs[:30])
    return quiet, loaded, a


def _demo(out: Path, procedure: str = "demo.yaml") -> Path:
    """The command of conftest's `demo_run` fixture (whose run is the quiet one), quiet."""
    proc = subprocess.run([sys.executable, "-m", "bench", "run",
                           str(CONFIGS / "procedures" / procedure), "--yes",
                           "--quiet", "--out", str(out)],
                          capture_output=True, text=True, timeout=900, check=False)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    runs = [p for p in out.iterdir() if (p / "result.json").is_file()]
    assert len(runs) == 1, list(out.iterdir())
    return runs[0]


def _certificate_text(run: Path) -> str:
    html = (run / "certificate.html").read_text(encoding="utf-8")
    return _normal(html)


@pytest.mark.timeout(1200)
def test_the_demo_gives_the_same_numbers_quiet_and_beside_two_busy_processes(
        demo_run: DemoRun, tmp_path: Path) -> None:
    assert demo_run.status == 0, demo_run.stderr[-3000:]
    quiet, loaded, a = _quiet_and_loaded(_demo, tmp_path, demo_run.dir)
    # a check that can fail: the results carry figures, and the raw records are equal
    assert a["axes"]["outer"]["rates"], a["axes"]
    assert any(f["sha256"] for f in a["raw_files"])
    ca, cb = _certificate_text(quiet), _certificate_text(loaded)
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
        drift_demo_run: DemoRun, tmp_path: Path) -> None:
    """The drift-pulse kind (docs/method.md B) on the co-simulation: the DMMs' and the
    generator's waits are on stand time (drivers/dmm.py), so the pulse triggers, the
    records' sample times and every reading are the same under any load."""
    assert drift_demo_run.status == 0, drift_demo_run.stderr[-3000:]
    quiet, loaded, a = _quiet_and_loaded(lambda out: _demo(out, "drift-demo.yaml"), tmp_path,
                                         drift_demo_run.dir)
    # a check that can fail: both gyros carry their cycles, and the raw records are equal
    for g in ("x", "y"):
        assert len(a["drift"]["axes"][g]["cycles"]) == 20, a["drift"]["axes"][g]
    assert {f["path"] for f in a["raw_files"]} >= {"raw/s1/x-dmm.jsonl", "raw/s1/awg.jsonl"}
    ca, cb = _certificate_text(quiet), _certificate_text(loaded)
    assert ca == cb, [(x, y) for x, y in zip(ca.splitlines(), cb.splitlines(), strict=False)
                      if x != y][:10]


def _static_first(folder: Path) -> Path:
    """A check run of the control charts' baseline (tests/conftest.py `check_procedure`,
    seed 1: one rate, its first step the FOG's static record, started the instant the
    instruments are open), the same files' bytes and names as the session's
    `control_baseline` run 1, in a subprocess as an operator starts it."""
    proc = check_procedure(folder, 1)
    out = subprocess.run([sys.executable, "-m", "bench", "run", str(proc), "--yes", "--quiet",
                          "--out", str(folder / "runs")],
                         capture_output=True, text=True, timeout=600, check=False)
    assert out.returncode in (0, 1), out.stdout + out.stderr
    return Path(out.stdout.strip().splitlines()[-1])


@pytest.mark.timeout(900)
def test_a_static_record_at_the_start_begins_on_the_same_sample_under_load(
        control_baseline: ControlBaseline, tmp_path: Path) -> None:
    """The static record began at the newest FOG sample the reader held: the one due at
    that very instant was there on a quiet machine and not yet on a loaded one, so every
    later step moved by 1 ms (the control charts' drive settle time moved with it, and
    tests/test_control.py saw a false WE4 beside two busy processes). Now the clock alone
    places it (procedures/rate_ladder/kind.py `_do_static`). The quiet run is the
    session's first baseline run (made in the test process, by the console script's
    `main`), the loaded one the same files run by `bench` beside two busy processes."""
    quiet, loaded, _ = _quiet_and_loaded(_static_first, tmp_path, control_baseline.run(1))
    drive = [(q.read_text(), lo.read_text()) for q, lo in
             zip(sorted(quiet.glob("raw/s*/outer-drive.jsonl")),
                 sorted(loaded.glob("raw/s*/outer-drive.jsonl")), strict=True)]
    assert drive and all(x == y for x, y in drive)   # commands and settles, to the ms
    static = [json.loads(ln) for ln in (quiet / "events.jsonl").read_text().splitlines()
              if '"event":"static"' in ln.replace(" ", "")]
    # the FOG opens at the clock's 0.05 s (after the drive's identity read) and the record
    # starts with its first sample, the first after 0.05 s: sample 51, 5 s long
    assert [(round(e["t_s"] - 5.0, 9), e["fog_from"]) for e in static] == [(0.051, 51)], static
