"""Shared test helpers: the CLI (`bench`, `bench_bg` in a subprocess as an operator starts
it; `cli` in this process for commands that start no run), the session's demo runs read
by many files (`demo_run`, `drift_demo_run`: copy before writing; `control_baseline`,
the control charts' baseline of short check runs, made run by run as tests ask), each
made once for the whole session, however many worker processes share it; the twins (`twins`
starts drive, counter and FOG twins on their real channels and stops them at the test's
end; `one_axis_stand`), a small tmpfs (`small_disk`) and `unavailable` for a missing
server (a failure in CI)."""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import os
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

pytest_plugins = ["tests.netguard", "tests.schedule", "tests.filetimes"]

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = ROOT / "configs"
#: the serials the outer axis's twins of configs/stands/sim-two-axis.yaml report (the FOG's
#: as the stand states it, the counter's *IDN? field, the drive's 0x1018:4): the records
#: keep check values per instrument under them
OUTER_SERIALS = {"fog": "1760-20231", "counter": "MY62000117", "drive": "41001"}


def unavailable(reason: str) -> None:
    """A test's server or facility (PostgreSQL, a browser, a tmpfs) is
    missing: in CI (`CI` set, as .ci/run's caller does) that is a failure, since .ci/run
    installs them and a skip would hide the gap; on a developer's machine, a skip saying so.
    """
    if os.environ.get("CI"):
        pytest.fail(f"{reason} (CI installs it: see .ci/run)", pytrace=False)
    pytest.skip(reason)


@pytest.fixture(scope="session")
def pg() -> Any:
    """One PostgreSQL server per test process (tests/pg_server.py), started on first use."""
    from tests.pg_server import PgServer, PgUnavailable

    try:
        server = PgServer().start()
    except PgUnavailable as e:
        unavailable(f"no PostgreSQL server for the records and register tests: {e}")
    try:
        yield server
    finally:
        server.stop()


#: the argon2id parameters of the suite's password hashes (`cheap_password_hashes`): one
#: pass over 64 KiB, lane 1, the hash and salt lengths of the register's own
CHEAP_ARGON2 = {"time_cost": 1, "memory_cost": 64, "parallelism": 1}


@pytest.fixture(scope="session", autouse=True)
def cheap_password_hashes() -> Iterator[Callable[[], Any]]:
    """The register hashes the suite's passwords with CHEAP_ARGON2, not its own RFC 9106
    parameters (64 MiB, 3 passes, 4 lanes: 0.3-0.45 CPU s a hash or a check on this
    2-core machine, ~14 of them to fill one test register and one per `bench authorise`),
    which are a brake on guessing, not something a test asserts but the one that checks
    them (tests/test_password_hashing.py, with the register's own hasher this yields). A
    hash records its parameters, so a `bench` the suite starts in its own process checks
    these passwords as cheaply, and hashes a password it sets with the register's own.
    Every refusal, lockout and role check runs as before: only the work per hash is less."""
    from argon2 import PasswordHasher

    from bench.app.register import model

    shipped = model._hasher
    cheap = PasswordHasher(**CHEAP_ARGON2)
    model._hasher = lambda: cheap
    try:
        yield shipped
    finally:
        model._hasher = shipped


@pytest.fixture
def small_disk(tmp_path: Path) -> Any:
    """A small file system of its own (tmpfs), to be filled: needs root and mount(2)."""
    mnt = tmp_path / "small"
    mnt.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=48m", "tmpfs", str(mnt)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        unavailable(f"cannot mount a tmpfs here ({done.stderr.strip()}): the full-disk cell "
                    "needs root and mount(2)")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


@pytest.fixture
def configs() -> Path:
    return CONFIGS


class JournalTail:
    """A run's events.jsonl read as it grows: each `read` parses only the lines completed
    since the last one (a line is complete when its newline is written). The cuts and
    fault injections poll a journal every 10 ms; parsing the whole of it each time cost
    ~0.8 ms a poll on the demo's 172 lines, 8 % of a core over a run, taken from the run
    itself where it shares the test's process (its interpreter lock)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._offset = 0
        self.events: list[dict[str, Any]] = []

    def read(self) -> list[dict[str, Any]]:
        """Every complete line so far, as its JSON mapping (a line that is not JSON, a
        crash's torn tail, is skipped, as the bench's own reader does)."""
        try:
            with open(self.path, "rb") as fh:
                fh.seek(self._offset)
                chunk = fh.read()
        except FileNotFoundError:
            return self.events
        end = chunk.rfind(b"\n") + 1
        for line in chunk[:end].split(b"\n"):
            with contextlib.suppress(ValueError):
                if line.strip():
                    self.events.append(json.loads(line))
        self._offset += end
        return self.events


def when_step_starts(run: Any, match: Callable[[dict[str, Any]], bool],
                     action: Callable[[], Any], delay_s: float = 0.05) -> threading.Thread:
    """Call `action` (e.g. inject a fault into a twin) once a matching step of the run
    (a RunDir) has started."""
    tail = JournalTail(run.path / "events.jsonl")

    def watch() -> None:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if any(e.get("event") == "step_start" and match(e) for e in tail.read()):
                time.sleep(delay_s)
                action()
                return
            time.sleep(0.01)
    t = threading.Thread(target=watch, daemon=True)
    t.start()
    return t


# -- the CLI ---------------------------------------------------------------------------------

def _env_without_lab() -> dict[str, str]:
    """A lab settings file named in the developer's environment must not sign test runs."""
    from bench.app.dcc.settings import ENV_LAB
    return {k: v for k, v in os.environ.items() if k != ENV_LAB}


def env_as_shipped() -> dict[str, str]:
    """`_env_without_lab` with the certificate's figure workers as the bench has them
    outside the suite (`figure_workers` below): for the runs that stand for the shipped
    commands (the session's demo runs, the determinism test's loaded runs)."""
    env = _env_without_lab()
    if env.pop(_FIGURE_WORKERS_MARK, None):
        env.pop(ENV_FIGURE_WORKERS, None)
    return env


def bench(*args: str, timeout: float = 240, env: dict[str, str] | None = None
          ) -> subprocess.CompletedProcess[str]:
    """`bench ARGS` in a subprocess, as an operator starts it (its own interpreter, signal
    handlers and twins), from the checkout, without the developer's lab file (`env`, if
    given, is the whole environment)."""
    return subprocess.run([sys.executable, "-m", "bench", *args], cwd=ROOT, text=True,
                          capture_output=True, timeout=timeout,
                          env=_env_without_lab() if env is None else env)


def bench_bg(*args: str, new_session: bool = False,
             env: dict[str, str] | None = None) -> subprocess.Popen[str]:
    """`bench ARGS` started in the background (to be interrupted or raced); `new_session`:
    in a process group of its own, as a shell starts a command (to be sent a terminal's
    signals with os.killpg); `env`, if given, is the whole environment."""
    return subprocess.Popen([sys.executable, "-m", "bench", *args], cwd=ROOT, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env=_env_without_lab() if env is None else env,
                            start_new_session=new_session)


def wait_for_cut(p: subprocess.Popen[str], out: Path,
                 when: Callable[[list[dict[str, Any]]], bool], within_s: float) -> Path:
    """The run directory of `bench run ... --out OUT` (process `p`) once `when(events)`
    holds, polled every 10 ms; fails if the run ends first or does not get there within
    `within_s` of real time (the caller kills `p` on failure)."""
    run_dir = None
    tail: JournalTail | None = None
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline and p.poll() is None:
        if tail is None:
            # the run directory, not records.sqlite beside it (glob order is the disk's)
            logs = list(out.glob("*/events.jsonl")) if out.exists() else []
            if logs:
                run_dir, tail = logs[0].parent, JournalTail(logs[0])
        if tail is not None and when(tail.read()):
            break
        time.sleep(0.01)
    assert run_dir is not None and p.poll() is None, "the run ended before the cut"
    assert when(_journal(run_dir)), f"the cut's moment not reached within {within_s} s"
    return run_dir


def journal_lines(run: Any) -> list[dict[str, Any]]:
    """Every event of a run (a RunDir) as the JSON mapping written on its line: what a
    test that looks at the journal's bytes reads (the run's readers take its events)."""
    from bench.core.journal_codec import read_jsonl
    return list(read_jsonl(run.path / "events.jsonl"))


def _journal(run_dir: Path) -> list[dict[str, Any]]:
    """The journal's complete lines: the bench may be writing the last one as it is read
    (a line is complete when its newline is written; CI saw a half line, 28 Nov)."""
    text = (run_dir / "events.jsonl").read_text()
    return [json.loads(line) for line in text.split("\n")[:-1] if line]


def cli(*args: str) -> subprocess.CompletedProcess[str]:
    """`bench ARGS` in this process (the console script's own `main`): for commands that
    start no run, so no interpreter start-up per call."""
    from bench.app.cli import main
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(args))
    return subprocess.CompletedProcess(["bench", *args], code, out.getvalue(), err.getvalue())


def run_dir_of(out: subprocess.CompletedProcess[str]) -> Path:
    """The run directory `bench run` prints last on stdout."""
    lines = out.stdout.strip().splitlines()
    assert lines, f"bench printed no run directory (exit {out.returncode}): {out.stderr[-3000:]}"
    return Path(lines[-1])


# -- shared runs ------------------------------------------------------------------------------
# A run that tests only read is made once for the whole session: the suite's worker
# processes (pytest-xdist, a file per worker) share one folder, and the first worker to ask
# for a run makes it while any other waits for it on a lock (`_session_lock`).

def _shared_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The folder every process of this test session sees: beside the workers' own
    temporary folders under pytest-xdist, in this process's own otherwise."""
    base = tmp_path_factory.getbasetemp()
    root = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "shared-runs"
    root.mkdir(parents=True, exist_ok=True)
    return root


@contextlib.contextmanager
def _session_lock(root: Path, name: str) -> Iterator[None]:
    """One process of the session at a time holds `name` (an flock, released on exit or
    when the holder dies)."""
    import fcntl

    with open(root / f"{name}.lock", "w") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


@dataclasses.dataclass(frozen=True)
class DemoRun:
    """One `bench run` of a shipped example, done once per test session and read by many
    tests: never change its folder (copy it with `copy_to`)."""

    out: Path     # the --out folder the run was started with
    status: int
    stdout: str
    stderr: str
    dir: Path
    result: dict[str, Any]

    def copy_to(self, dest: Path) -> Path:
        """The whole runs folder (the run and its records beside it) copied under `dest`;
        the copy's run directory."""
        shutil.copytree(self.dir.parent, dest)
        return dest / self.dir.name


def _demo_run(procedure: str, out: Path) -> DemoRun:
    """The shipped example as an operator runs it, its figures drawn beside the PDF as the
    bench does by default (`env_as_shipped`)."""
    done = bench("run", str(CONFIGS / "procedures" / procedure), "--yes", "--out", str(out),
                 timeout=300, env=env_as_shipped())
    run_dir = run_dir_of(done)
    result_file = run_dir / "result.json"
    result = json.loads(result_file.read_text()) if result_file.exists() else {}
    return DemoRun(out, done.returncode, done.stdout, done.stderr, run_dir, result)


def _shared_demo_run(tmp_path_factory: pytest.TempPathFactory, procedure: str,
                     name: str) -> DemoRun:
    """`_demo_run` once for the session: made by the first process to ask, read back from
    its record (`NAME.json`: status, output and run directory) by every other."""
    root = _shared_root(tmp_path_factory)
    record = root / f"{name}.json"
    with _session_lock(root, name):
        if not record.exists():
            run = _demo_run(procedure, root / name)
            record.write_text(json.dumps({"out": str(run.out), "status": run.status,
                                          "stdout": run.stdout, "stderr": run.stderr,
                                          "dir": str(run.dir)}))
    made = json.loads(record.read_text())
    run_dir = Path(made["dir"])
    result_file = run_dir / "result.json"
    result = json.loads(result_file.read_text()) if result_file.exists() else {}
    return DemoRun(Path(made["out"]), made["status"], made["stdout"], made["stderr"],
                   run_dir, result)


@pytest.fixture(scope="session")
def demo_run(tmp_path_factory: pytest.TempPathFactory) -> DemoRun:
    """configs/procedures/demo.yaml (the two-axis rate ladder), run once for the session."""
    return _shared_demo_run(tmp_path_factory, "demo.yaml", "demo-run")


@pytest.fixture(scope="session")
def drift_demo_run(tmp_path_factory: pytest.TempPathFactory) -> DemoRun:
    """configs/procedures/drift-demo.yaml (the paper's case 70/80), run once."""
    return _shared_demo_run(tmp_path_factory, "drift-demo.yaml", "drift-demo-run")


def check_procedure(folder: Path, seed: int, scale_step: tuple[int, float] | None = None
                    ) -> Path:
    """A short check run of the two-axis twin's outer axis (one rate, two turns, its FOG's
    static record first), the stand's seed `seed`: the runs of the control charts'
    baseline. `scale_step` (from_run, rel) steps the FOG's scale from that run of the
    records on. The files, `stand-SEED.yaml` and `check-SEED.yaml` (naming the stand by
    its relative path), are the same bytes in any folder: result.json names and hashes
    them, so two folders' runs of one seed can be compared."""
    import yaml

    stand = yaml.safe_load((CONFIGS / "stands" / "sim-two-axis.yaml").read_text())
    stand["sim"]["seed"] = seed
    if scale_step is not None:    # no run_number: the records count the runs
        stand["sim"]["axes"]["outer"]["fog"]["scale_step"] = {"from_run": scale_step[0],
                                                             "rel": scale_step[1]}
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"stand-{seed}.yaml").write_text(yaml.safe_dump(stand))
    proc = folder / f"check-{seed}.yaml"
    proc.write_text(yaml.safe_dump({
        "procedure": "rate-ladder", "title": "Assurance check run",
        "stand": f"stand-{seed}.yaml", "turns": 2, "static_record_s": 5, "harmonics": 2,
        "prompts": False, "axes": {"outer": {"rates_dps": [50]}},
        "tolerance": {"rate_error": [{"rel": 1e-5}]},
        "certificate": {"laboratory": "Assurance test lab"}}))
    return proc


def check_run(proc: Path, runs: Path) -> tuple[Path, subprocess.CompletedProcess[str]]:
    """`bench run PROC --yes --quiet --out RUNS` in this process (the console script's
    `main`: the runs of a baseline share one interpreter's start-up and imports; the twins
    still talk over their real channels): the run directory and the command's output."""
    out = cli("run", str(proc), "--yes", "--quiet", "--out", str(runs))
    assert out.returncode in (0, 1), out.stdout[-2000:] + out.stderr[-3000:]
    return run_dir_of(out), out


@dataclasses.dataclass(frozen=True)
class ControlBaseline:
    """The control charts' baseline (bench/app/records/control.py): `size` check runs
    (`check_procedure`, seeds 1 to `size`) made in order in one runs folder, `runs`, whose
    records hold each run's check values. Made once for the session and run by run as
    tests ask: `run(1)` makes the first alone. Never change its folder: `copy_to` copies
    it. Its size is the pytest setting `control_baseline_runs` (pyproject.toml), at least
    the records' `BASELINE_RUNS` for the tests that judge a run after the baseline."""

    folder: Path      # the stand and procedure files, the runs folder, the locks
    size: int

    @property
    def runs(self) -> Path:
        return self.folder / "runs"

    def run(self, n: int) -> Path:
        """The n-th run's directory (1 <= n <= size), made, with each before it, by the
        first process of the session to ask."""
        assert 1 <= n <= self.size, (n, self.size)
        for i in range(1, n + 1):
            record = self.folder / f"run-{i}.dir"
            with _session_lock(self.folder, f"run-{i}"):
                if not record.exists():       # runs 1 to i - 1 are made: the order holds
                    record.write_text(str(check_run(check_procedure(self.folder, i),
                                                    self.runs)[0]))
        return Path(record.read_text())

    def dirs(self) -> list[Path]:
        """Every run of the baseline, in order."""
        self.run(self.size)
        return [self.run(i) for i in range(1, self.size + 1)]

    def copy_to(self, dest: Path) -> list[Path]:
        """The runs folder (the runs and their records) copied to `dest`, every run made
        first: the copies' run directories, in order."""
        names = [d.name for d in self.dirs()]
        shutil.copytree(self.runs, dest)
        return [dest / name for name in names]


#: the pytest setting (`[tool.pytest.ini_options]` in pyproject.toml, or `-o NAME=N`) that
#: sets how many check runs `control_baseline` makes
BASELINE_SETTING = "control_baseline_runs"


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addini(BASELINE_SETTING, "check runs in the session's control_baseline fixture "
                  "(tests/conftest.py); the control charts' tests need at least the "
                  "records' BASELINE_RUNS (default: that number)", default=None)
    parser.addini(FIGURE_WORKERS_SETTING, "the certificate's figure workers "
                  f"({ENV_FIGURE_WORKERS}) in the suite's runs but the shipped demos' "
                  "(tests/conftest.py env_as_shipped); unset: the bench's default",
                  default=None)


#: the pytest setting (`[tool.pytest.ini_options]`, or `-o NAME=N`) that sets how many
#: worker processes draw a certificate's figures in the suite's runs
FIGURE_WORKERS_SETTING = "figure_workers"
#: bench/app/certificate/figures.py's variable (not imported: this module loads first)
ENV_FIGURE_WORKERS = "BENCH_FIGURE_WORKERS"
#: set beside it when the suite set it (a developer's own value is left alone); the
#: workers of pytest-xdist inherit both from the controller
_FIGURE_WORKERS_MARK = "RATEBENCH_SUITE_SET_FIGURE_WORKERS"
_SET_HERE: list[bool] = []     # this process set them (and unsets them at its end)


def pytest_configure(config: pytest.Config) -> None:
    """The figure workers of `figure_workers` for every run the suite makes, in this
    process and in each `bench` it starts: a spawned worker costs each certificate an
    interpreter and matplotlib's import (a check run's CPU 16-18 s with one, 10-12 s
    without, the same PNGs), and on a machine whose cores the suite's own workers already
    keep busy it draws nothing sooner. The shipped demos keep the bench's default
    (`env_as_shipped`), so the drawing beside the PDF is still run and compared
    (tests/test_determinism.py)."""
    value = config.getini(FIGURE_WORKERS_SETTING)
    if value in (None, "") or ENV_FIGURE_WORKERS in os.environ:
        return                # unset, or set by the developer or by the controller
    try:
        workers = int(str(value))
    except ValueError:
        workers = -1
    if workers < 0:
        raise pytest.UsageError(f"{FIGURE_WORKERS_SETTING} = {value!r}: a number of worker "
                                "processes, 0 or more")
    os.environ[ENV_FIGURE_WORKERS] = str(workers)
    os.environ[_FIGURE_WORKERS_MARK] = "1"
    _SET_HERE.append(True)


def pytest_unconfigure(config: pytest.Config) -> None:
    if _SET_HERE:
        os.environ.pop(ENV_FIGURE_WORKERS, None)
        os.environ.pop(_FIGURE_WORKERS_MARK, None)
        _SET_HERE.clear()


def baseline_runs(config: pytest.Config) -> int:
    """The setting's number of runs (the records' `BASELINE_RUNS` where it is not set)."""
    value = config.getini(BASELINE_SETTING)
    if value in (None, ""):
        from bench.app.records.control import BASELINE_RUNS
        return BASELINE_RUNS
    try:
        runs = int(str(value))
    except ValueError:
        runs = 0
    if runs < 1:
        raise pytest.UsageError(f"{BASELINE_SETTING} = {value!r}: a number of runs, 1 or more")
    return runs


@pytest.fixture(scope="session")
def control_baseline(tmp_path_factory: pytest.TempPathFactory,
                     pytestconfig: pytest.Config) -> ControlBaseline:
    """The control charts' baseline, shared by the session (see `ControlBaseline`); its
    size the setting `control_baseline_runs`."""
    folder = _shared_root(tmp_path_factory) / "control-baseline"
    folder.mkdir(exist_ok=True)
    return ControlBaseline(folder, baseline_runs(pytestconfig))


# -- twins -----------------------------------------------------------------------------------

def one_axis_stand(clock: Any, axis: str = "outer", *, seed: int = 3,
                   truth: Any = None, max_rate_dps: float = 1000.0) -> Any:
    """A simulated stand of one axis (its truth `AxisTruth()` unless given) on `clock`."""
    from sims.stand import AxisTruth, SimulatedStand, StandTruth
    return SimulatedStand(StandTruth(seed=seed, axes={axis: truth or AxisTruth()}),
                          {axis: max_rate_dps}, clock)


def drive_settings(channel: str, node_id: int = 2, **kw: Any) -> Any:
    """A stand's drive block for a test's axis or twin on the virtual CAN bus `channel`
    (the limits of tests/test_axis.py's stand, 400 deg/s and 200 deg/s^2, unless given)."""
    from drivers.drive_settings import DriveSettings
    return DriveSettings(**{"interface": "virtual", "channel": channel, "node_id": node_id,
                            "max_rate_dps": 400.0, "max_accel_dps2": 200.0, **kw})


class Twins:
    """Twins started for one test, each on its real channel (a CAN bus, a pty, TCP), and
    each stopped when the test ends, however it ends (the `twins` fixture)."""

    def __init__(self, stack: contextlib.ExitStack) -> None:
        self._stack = stack

    def drive(self, stand: Any, axis: str = "outer", *, node_id: int = 2,
              channel: str | None = None, **kw: Any) -> Any:
        """A CiA 402 drive twin on a virtual CAN bus of its own (unless `channel` names one:
        `twin.channel` says which)."""
        import uuid

        from sims.drive_truth import DriveTruth
        from sims.drive_twin import DriveTwin
        given = {k: kw.pop(k) for k in ("counts_per_rev", "controller_node_id") if k in kw}
        twin = DriveTwin(stand, axis, drive_settings(
            channel or f"test-{uuid.uuid4().hex[:10]}", node_id, **given), DriveTruth(**kw))
        twin.start()
        self._stack.callback(twin.stop)
        return twin

    def counter(self, stand: Any, axis: str = "outer", *, model: str = "keysight-53230a",
                truth: Any = None, **kw: Any) -> Any:
        """A counter twin serving SCPI on TCP 127.0.0.1 (`twin.resource` to open it);
        `truth`: the axis's truth it reads (default: the stand's)."""
        from drivers.counter_settings import CounterSettings
        from sims.counter_twin import CounterTwin
        twin = CounterTwin(stand, axis, CounterSettings(resource="", model=model), truth, **kw)
        twin.start()
        self._stack.callback(twin.stop)
        return twin

    def fog(self, stand: Any, axis: str = "outer", **kw: Any) -> Any:
        """A KVH FOG twin on a pseudo-terminal (`twin.path` to open it)."""
        from sims.fog_twin import FogTwin
        twin = FogTwin(stand, axis, **kw)
        twin.start()
        self._stack.callback(twin.stop)
        return twin

    def close_later(self, thing: Any, close: str = "close") -> Any:
        """A client of a twin, closed at the test's end before the twins stop."""
        self._stack.callback(getattr(thing, close))
        return thing


@pytest.fixture
def twins() -> Any:
    with contextlib.ExitStack() as stack:
        yield Twins(stack)
