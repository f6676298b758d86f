"""Each test file's wall and CPU seconds, and when it started and ended on which worker: the
numbers tests/schedule.py's table of slow files is kept by, printed at the session's end
(a plugin of the suite, named in tests/conftest.py's `pytest_plugins`).

A file's wall time on a shared machine moves with the load beside it; its CPU seconds
(the test process's own, and those of the child processes it waited for: each `bench` a
test starts) move far less, and on two cores they are what the two workers share. Setup,
call and teardown are counted, so a module fixture's runs count for its file and a session
fixture's (`demo_run`) for the first file that asked for it. Under pytest-xdist each worker
sends its files' times to the controller (`workeroutput`), which prints them with each
worker's end: the time one worker ran alone at the end is the difference of the ends.
"""

from __future__ import annotations

import os
import resource
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import pytest

#: the files printed, most CPU first (the rest are short: their sum is printed)
SHOWN = 30
_KEY = "ratebench_filetimes"


@dataclass
class FileTime:
    """One file on one worker: seconds since the session's start, wall and CPU seconds."""

    worker: str
    start_s: float
    end_s: float
    wall_s: float = 0.0
    cpu_s: float = 0.0
    tests: int = 0


class _Clock:
    def __init__(self) -> None:
        self.t0 = time.time()
        self.files: dict[str, FileTime] = {}
        self.workers: dict[str, float] = {}     # worker -> seconds since t0 of its end


_CLOCK = _Clock()


def _cpu_s() -> float:
    """User and system seconds of this process, of its children waited for, and of the
    analysis workers' fork server with the workers it has reaped."""
    mine = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return mine.ru_utime + mine.ru_stime + kids.ru_utime + kids.ru_stime + _fork_server_s()


def _fork_server_s() -> float:
    """The fork server (bench/core/engine.py `_worker_context`) lives as long as this
    process and reaps the analysis workers it forks, so their CPU reaches RUSAGE_CHILDREN
    only when the server ends: read live from /proc until then (when it is reaped its
    total moves into RUSAGE_CHILDREN and this reads 0, so the sum stays continuous)."""
    from multiprocessing import forkserver
    pid = getattr(getattr(forkserver, "_forkserver", None), "_forkserver_pid", None)
    if not pid:
        return 0.0
    try:
        stat = Path(f"/proc/{pid}/stat").read_text(encoding="ascii")
    except OSError:
        return 0.0
    fields = stat.rsplit(")", 1)[1].split()      # from field 3 (state) on: proc(5)
    ticks = sum(int(x) for x in fields[11:15])   # utime, stime, cutime, cstime
    return ticks / os.sysconf("SC_CLK_TCK")


def _worker(config: pytest.Config) -> str:
    return str(getattr(config, "workerinput", {}).get("workerid", "main"))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item) -> Iterator[None]:
    wall0, cpu0 = time.time(), _cpu_s()
    yield
    now = time.time()
    row = _CLOCK.files.setdefault(item.path.name, FileTime(
        _worker(item.config), wall0 - _CLOCK.t0, 0.0))
    row.end_s = now - _CLOCK.t0
    row.wall_s += now - wall0
    row.cpu_s += _cpu_s() - cpu0
    row.tests += 1


def pytest_sessionfinish(session: pytest.Session) -> None:
    """A worker hands its files' times to the controller, on the session's clock (the
    controller's start: the workers start within a second of it)."""
    workeroutput: dict[str, Any] | None = getattr(session.config, "workeroutput", None)
    if workeroutput is not None:
        workeroutput[_KEY] = {"t0": _CLOCK.t0, "end": time.time(),
                              "files": {n: asdict(f) for n, f in _CLOCK.files.items()}}


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node: Any, error: Any) -> None:
    """The controller (pytest-xdist's hook): a worker's files, on the controller's clock."""
    got = getattr(node, "workeroutput", {}).get(_KEY)
    if not got:
        return
    shift = got["t0"] - _CLOCK.t0
    for name, row in got["files"].items():
        ft = FileTime(**row)
        ft.start_s += shift
        ft.end_s += shift
        _CLOCK.files[name] = ft
    _CLOCK.workers[str(node.gateway.id)] = got["end"] - _CLOCK.t0


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    files = _CLOCK.files
    if not files:
        return
    with open("/proc/loadavg") as fh:
        load = " ".join(fh.read().split()[:3])
    ends = ", ".join(f"{w} ended at {s:.0f} s" for w, s in sorted(_CLOCK.workers.items()))
    terminalreporter.section(f"file times (load average {load} at the end{'; ' if ends else ''}"
                             f"{ends})")
    terminalreporter.write_line("   CPU s   wall s  start s    end s  worker  tests  file")
    ranked = sorted(files.items(), key=lambda kv: -kv[1].cpu_s)
    for name, f in ranked[:SHOWN]:
        terminalreporter.write_line(f"{f.cpu_s:8.1f} {f.wall_s:8.1f} {f.start_s:8.1f} "
                                    f"{f.end_s:8.1f}  {f.worker:6s} {f.tests:5d}  {name}")
    rest = [f for _, f in ranked[SHOWN:]]
    if rest:
        terminalreporter.write_line(f"{sum(f.cpu_s for f in rest):8.1f} "
                                    f"{sum(f.wall_s for f in rest):8.1f}  the other "
                                    f"{len(rest)} files")
    last = sorted(files.items(), key=lambda kv: kv[1].end_s)[-4:]
    terminalreporter.write_line("the last files to end: " + ", ".join(
        f"{n} ({f.worker}, {f.start_s:.0f}-{f.end_s:.0f} s)" for n, f in last))
