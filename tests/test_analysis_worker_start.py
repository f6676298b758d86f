"""bench/core/engine.py: how the analysis worker starts (issue 62).

A kind that names its worker's modules (the rate ladder's WORKER_PRELOAD) has its workers
forked by one fork server per bench process, which imported them once. What a spawned
worker had must hold for a forked one: the bench's environment as of the session, a
priority WORKER_NICE below the bench's as of the session, one BLAS thread, and an end
when the bench ends, however it ends (SIGKILL included). Real processes throughout.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from bench.core.engine import WORKER_NICE, AnalysisWorker
from tests.conftest import ROOT
from tests.test_session_lifecycle import _alive

LADDER = "procedures.rate_ladder.kind"
#: what the ladder's worker jobs need (its WORKER_PRELOAD), imported before any job
LADDER_MODULES = ("procedures.rate_ladder.analysis", "scipy.linalg", "numpy")

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="the fork server, pidfds and per-thread nice: Linux")


#: the worker's first job, a builtin's (unpickling it imports nothing, as this file's
#: functions would): which of the ladder's modules the worker has before any job
HAD = f"{{m: m in __import__('sys').modules for m in {LADDER_MODULES!r}}}"


def _report(probe_env: tuple[str, ...]) -> dict[str, Any]:
    """Run in the worker: who its parent is, its environment, and every thread's
    priority once BLAS has been woken by a product."""
    import numpy as np
    from threadpoolctl import threadpool_info

    a = np.ones((64, 4096))
    _ = a @ a.T
    tids = [int(t) for t in os.listdir("/proc/self/task")]
    return {"pid": os.getpid(), "ppid": os.getppid(),
            "env": {k: os.environ.get(k) for k in probe_env},
            "blas_threads": [i["num_threads"] for i in threadpool_info()
                             if i["user_api"] == "blas"],
            "nice": {tid: os.getpriority(os.PRIO_PROCESS, tid) for tid in tids}}


def _session(probe_env: tuple[str, ...] = (), preload: str | None = LADDER) -> dict[str, Any]:
    """One session's worker, as the engine starts it for the ladder, and its report."""
    got: dict[str, Any] = {}
    done = threading.Event()

    def on_done(result: Any, error: BaseException | None) -> None:
        got["result"], got["error"] = result, error
        done.set()

    worker = AnalysisWorker()
    try:
        worker.start(preload=preload)
        worker.submit(eval, HAD, on_done=lambda had, _error: got.update(had=had))
        worker.submit(_report, probe_env, on_done=on_done)
        assert done.wait(120), "the worker did not answer"
    finally:
        worker.close()
    assert got["error"] is None, got["error"]
    report: dict[str, Any] = {**got["result"], "had": got["had"]}
    return report


def test_each_sessions_worker_is_a_fork_of_one_server_with_the_kinds_modules_imported(
        ) -> None:
    first, second = _session(), _session()
    for report in (first, second):
        assert report["had"] == dict.fromkeys(LADDER_MODULES, True)
        assert report["ppid"] != os.getpid()     # the fork server's child, not the bench's
        assert report["blas_threads"] and set(report["blas_threads"]) == {1}
    assert first["pid"] != second["pid"]         # a worker per session
    assert first["ppid"] == second["ppid"]       # one server for both
    server = Path(f"/proc/{first['ppid']}/cmdline").read_bytes()
    assert b"multiprocessing.forkserver" in server, server
    assert int(Path(f"/proc/{first['ppid']}/stat").read_text().rsplit(")", 1)[1].split()[1]) \
        == os.getpid()                           # the bench's child: it started the server


def test_the_worker_has_the_benchs_environment_as_of_its_session(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The server took the bench's environment when it started; a test's setenv and
    delenv after it (or a setting the bench changed) reach the worker all the same, and
    the one BLAS thread the server's imports pinned stays."""
    probe = ("RATEBENCH_PROBE_KEPT", "RATEBENCH_PROBE_GONE", "RATEBENCH_PROBE_NEW",
             "OPENBLAS_NUM_THREADS")
    monkeypatch.setenv("RATEBENCH_PROBE_KEPT", "kept")
    monkeypatch.setenv("RATEBENCH_PROBE_GONE", "before")
    before = _session(probe)["env"]
    assert before["RATEBENCH_PROBE_KEPT"] == "kept"
    assert before["RATEBENCH_PROBE_GONE"] == "before"
    assert before["RATEBENCH_PROBE_NEW"] is None
    monkeypatch.delenv("RATEBENCH_PROBE_GONE")
    monkeypatch.setenv("RATEBENCH_PROBE_NEW", "new")
    monkeypatch.setenv("RATEBENCH_PROBE_KEPT", "changed")
    after = _session(probe)["env"]
    assert after == {"RATEBENCH_PROBE_KEPT": "changed", "RATEBENCH_PROBE_GONE": None,
                     "RATEBENCH_PROBE_NEW": "new", "OPENBLAS_NUM_THREADS": "1"}


def test_a_bare_submits_worker_runs_below_the_bench_in_every_thread() -> None:
    """A worker no kind started (`submit` alone: spawned if no server runs yet, else
    forked): every thread WORKER_NICE below the bench, BLAS's woken by the job's product."""
    report = _session(preload=None)
    assert len(report["nice"]) >= 2            # the job's thread and the bench watch
    low = min(os.getpriority(os.PRIO_PROCESS, 0) + WORKER_NICE, 19)
    assert all(n >= low for n in report["nice"].values()), report["nice"]


def test_every_worker_thread_runs_below_the_benchs_priority_as_of_its_session() -> None:
    """A second session started from a thread two steps lower than the bench's first: its
    worker, forked from a server started at the first's priority, is WORKER_NICE below
    the second's, in every thread (the job's, the bench watch, BLAS's)."""
    base = os.getpriority(os.PRIO_PROCESS, 0)
    first = _session()
    assert all(n >= min(base + WORKER_NICE, 19) for n in first["nice"].values()), first
    got: dict[str, Any] = {}

    def lower_then_start() -> None:
        got["bench_nice"] = os.nice(2)           # this thread only (Linux)
        got["report"] = _session()

    t = threading.Thread(target=lower_then_start)
    t.start()
    t.join(150)
    report = got["report"]
    assert len(report["nice"]) >= 2              # the job's thread and the bench watch
    low = min(got["bench_nice"] + WORKER_NICE, 19)
    assert got["bench_nice"] == min(base + 2, 19)
    assert all(n >= low for n in report["nice"].values()), (low, report["nice"])


def test_a_terminals_ctrl_c_leaves_the_worker_to_the_bench() -> None:
    """Ctrl-C at the terminal is SIGINT to the whole process group, the worker included.
    The bench handles it (stops the axes, then ends the worker); the worker, idle between
    jobs, died of it with a KeyboardInterrupt traceback printed above the bench's "ABORT:
    interrupted by SIGINT", and the job the bench waited for was lost."""
    pids: list[int] = []
    errors: list[BaseException | None] = []
    answered = threading.Semaphore(0)

    def on_done(pid: int, error: BaseException | None) -> None:
        pids.append(pid)
        errors.append(error)
        answered.release()

    worker = AnalysisWorker()
    try:
        worker.start(preload=LADDER)
        worker.submit(os.getpid, on_done=on_done)
        assert answered.acquire(timeout=120), "the worker did not answer"
        time.sleep(0.3)                          # idle, waiting for its next job
        os.kill(pids[0], signal.SIGINT)
        time.sleep(0.3)
        worker.submit(os.getpid, on_done=on_done)
        assert answered.acquire(timeout=120), "the worker did not answer after the SIGINT"
    finally:
        worker.close()
    assert errors == [None, None], errors
    assert pids[1] == pids[0]                    # the same worker, alive


#: a bench that starts a worker as the engine does, prints its pid and its server's, and
#: waits to be killed
KILLED_BENCH = f"""
import os, time
from bench.core.engine import AnalysisWorker
w = AnalysisWorker()
w.start(preload={LADDER!r})
pids = []
w.submit(os.getppid, on_done=lambda r, e: pids.append(r))
w.submit(os.getpid, on_done=lambda r, e: pids.append(r))
while len(pids) < 2:
    time.sleep(0.01)
print(*pids, flush=True)
time.sleep(600)
"""


@pytest.mark.timeout(120)
def test_a_sigkilled_bench_leaves_neither_its_worker_nor_the_fork_server() -> None:
    """The worker's parent is the fork server, which lives while any process holds its
    alive pipe: the worker itself among them. So the worker watches the bench's own
    pidfd: killed, the bench takes its worker with it, and the server follows; the
    bench's stdout, which both inherited, reaches its end."""
    p = subprocess.Popen([sys.executable, "-c", KILLED_BENCH], cwd=ROOT,
                         stdout=subprocess.PIPE, text=True,
                         env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        assert p.stdout is not None
        server, worker = map(int, p.stdout.readline().split())
        assert _alive(server) and _alive(worker)
        os.kill(p.pid, signal.SIGKILL)
        p.wait(timeout=10)
        t0 = time.monotonic()
        while (_alive(worker) or _alive(server)) and time.monotonic() - t0 < 10:
            time.sleep(0.05)
        assert not _alive(worker), "the worker outlived the bench by 10 s"
        assert not _alive(server), "the fork server outlived the bench by 10 s"
        assert p.stdout.read() == ""             # at its end: nobody holds it open
    finally:
        if p.poll() is None:
            p.kill()


@pytest.mark.parametrize("pidfd", [True, False], ids=["pidfd", "polled"])
def test_the_bench_watch_ends_the_worker_when_the_bench_ends(pidfd: bool) -> None:
    """`_watch_bench` alone, in a process of its own watching a stand-in bench: with a
    pidfd, and polled every PARENT_WATCH_S where there is none; and at once for a bench
    already gone."""
    hide = "" if pidfd else "del os.pidfd_open\n"
    bench = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
    code = (f"import os\n{hide}from bench.core.engine import _watch_bench\n"
            f"print('watching', flush=True)\n_watch_bench({bench.pid})\n")
    watcher = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, stdout=subprocess.PIPE,
                               text=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        assert watcher.stdout is not None and watcher.stdout.readline() == "watching\n"
        time.sleep(1.0)
        assert watcher.poll() is None, "the watch ended while the bench lived"
        bench.kill()
        bench.wait()
        assert watcher.wait(timeout=10) == 1
        gone = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                              env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=60)
        assert gone.returncode == 1                # the bench's pid is free now
    finally:
        for q in (bench, watcher):
            if q.poll() is None:
                q.kill()
