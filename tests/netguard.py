"""The network guard (issue 40): no test, and no Python subprocess a test starts, sends to
an address outside the machine.

A test that reaches the network passes or fails with the network it runs on, and on a lab
network it could talk to a real instrument; the suite is meant to run on the twins alone.
So every connect, send and multicast join outside 127.0.0.0/8 and ::1 is refused
(tests/netguard_site/netguard_core.py) and recorded before it is refused, and the test
that made it fails at teardown even if the code under test caught the error and went on.

Subprocesses get the guard through tests/netguard_site/sitecustomize.py (first on
PYTHONPATH) and write their attempts to the file RATEBENCH_NETGUARD_LOG names: one file
per test, or the session's file for subprocesses started outside any test (module and
session fixtures), which fails the session. The log directory is shared with pytest-xdist
workers through the environment, so the controller's summary counts every process's.
Non-Python processes (postgres, chromium) are not covered: tests/pg_server.py and the
browser tests keep those on loopback themselves.
"""

from __future__ import annotations

import itertools
import os
import re
import shutil
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

SITE = Path(__file__).resolve().parent / "netguard_site"
if str(SITE) not in sys.path:
    sys.path.insert(0, str(SITE))
import netguard_core as core  # noqa: E402  (a top-level module: the sitecustomize's own)

ENV_DIR = "RATEBENCH_NETGUARD_DIR"
SESSION_LOG = "session.jsonl"

_dir = pytest.StashKey[Path]()
_owner = pytest.StashKey[dict[str, str | None]]()   # the controller: env values to restore
_outside = pytest.StashKey[list[core.Attempt]]()
_serial = itertools.count()


def _is_worker(config: pytest.Config) -> bool:
    return hasattr(config, "workerinput")


def pytest_configure(config: pytest.Config) -> None:
    core.install()
    core.log_to_file(False)        # this process's attempts are drained by the fixture
    inherited = os.environ.get(ENV_DIR)
    if _is_worker(config) and inherited:
        config.stash[_dir] = Path(inherited)
        return
    # the controller (or a single process) makes the session's directory; a pytest run
    # inside a test (pytester) gets its own, not its parent session's
    log_dir = Path(tempfile.mkdtemp(prefix="ratebench-netguard-"))
    config.stash[_dir] = log_dir
    config.stash[_owner] = {k: os.environ.get(k) for k in (ENV_DIR, core.ENV_LOG, "PYTHONPATH")}
    paths = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    if str(SITE) not in paths:
        os.environ["PYTHONPATH"] = os.pathsep.join([str(SITE), *paths])
    os.environ[ENV_DIR] = str(log_dir)
    os.environ[core.ENV_LOG] = str(log_dir / SESSION_LOG)


def pytest_unconfigure(config: pytest.Config) -> None:
    saved = config.stash.get(_owner, None)
    if saved is None:
        return
    for k, v in saved.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v
    shutil.rmtree(config.stash[_dir], ignore_errors=True)


def _to_session_log(config: pytest.Config) -> None:
    """In-process attempts made outside any test go to the session's file."""
    core.append_log(str(config.stash[_dir] / SESSION_LOG), core.drain())


def _describe(attempts: list[core.Attempt]) -> str:
    me = os.getpid()
    lines = []
    for a in attempts:
        who = "this process" if a["pid"] == me else f"subprocess {a['pid']}: {a['argv']}"
        lines.append(f"  {a['call']} to {a['address']} ({who})")
        where = [s for s in a["stack"] if not any(f"{os.sep}{d}{os.sep}" in s
                                                  for d in ("_pytest", "pluggy"))]
        lines.extend(f"      {s}" for s in where[-5:])
    return "\n".join(lines)


@pytest.fixture(autouse=True)
def _network_guard(request: pytest.FixtureRequest,
                   monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    config = request.config
    _to_session_log(config)
    safe = re.sub(r"[^\w.-]+", "_", request.node.nodeid)[-100:]
    log = config.stash[_dir] / f"test-{safe}-{os.getpid()}-{next(_serial)}.jsonl"
    monkeypatch.setenv(core.ENV_LOG, str(log))
    yield
    mine = core.drain()
    core.append_log(str(log), mine)     # the summary counts files, this process's included
    attempts = core.read_log(str(log))
    if attempts:
        pytest.fail(f"network guard: {len(attempts)} refused attempt(s) to reach the "
                    f"network in this test:\n{_describe(attempts)}", pytrace=False)


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    config = session.config
    _to_session_log(config)
    if _is_worker(config):
        return
    outside = core.read_log(str(config.stash[_dir] / SESSION_LOG))
    config.stash[_outside] = outside
    if outside and session.exitstatus == 0:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter,
                            config: pytest.Config) -> None:
    if _is_worker(config):
        return
    log_dir = config.stash[_dir]
    total = sum(len(core.read_log(str(p))) for p in sorted(log_dir.glob("*.jsonl")))
    outside = config.stash.get(_outside, [])
    if outside:
        terminalreporter.write_line(
            f"network guard: {len(outside)} refused attempt(s) outside any test (a module "
            f"or session fixture, or a subprocess it started); the session fails:\n"
            f"{_describe(outside)}", red=True)
    terminalreporter.write_line(f"network guard: {total} refused attempts",
                                red=bool(total))
