"""One stop path (bench/core/stops.py): the registry's behaviour, a check that every
resource a command opens registers its stop as it is opened, and a real session on the
twins whose faulted axis ends at rest with outcomes that say so as fields."""

from __future__ import annotations

import ast
import functools
import re
import threading
from pathlib import Path
from typing import Any

import pytest

from bench.app.session import EXIT_ABORTED, RunSession
from bench.core.journal import RunDir
from bench.core.loader import load_config
from bench.core.stops import StopOutcome, Stops, attempt, register
from drivers.axis import AxisError, DriveUnreachable
from drivers.cia402 import OVER_TEMPERATURE
from tests.conftest import journal_lines, when_step_starts
from tests.test_fault_matrix import (  # its short one-axis ladder, its slow clock
    SLOW_CLOCK,
    _hear_silence_sooner,
    _procedure,
)

ROOT = Path(__file__).resolve().parents[1]


# -- the registry ------------------------------------------------------------------------

def test_stops_run_last_registered_first_and_once() -> None:
    ran: list[str] = []
    stops = Stops()
    for name in ("twin", "axis", "worker"):
        stops.add(name, functools.partial(ran.append, name), "twin")
    first = stops.run()
    assert ran == ["worker", "axis", "twin"]
    assert [o.what for o in first] == ["worker", "axis", "twin"]
    assert all(o.ok and o.error is None and not o.axis_moving for o in first)
    assert stops.run() == ()              # twice: nothing runs again
    assert ran == ["worker", "axis", "twin"]
    assert len(stops.outcomes) == 3


def test_a_failing_stop_does_not_skip_the_rest_and_is_typed() -> None:
    ran: list[str] = []
    stops = Stops()
    stops.add("first opened", lambda: ran.append("first"), "instrument")

    def unreachable() -> None:
        raise DriveUnreachable("outer", 0.8, 250, 1)

    def broken() -> None:
        raise AxisError("axis inner: leaving: disable: SDO timeout")

    stops.add("axis outer", unreachable, "axis")
    stops.add("axis inner", broken, "axis")
    outcomes = stops.run()
    assert ran == ["first"]
    inner, outer, first = outcomes
    assert (inner.ok, inner.error_type, inner.axis_moving) == (False, "AxisError", False)
    assert inner.error == "axis inner: leaving: disable: SDO timeout"
    assert (outer.ok, outer.error_type, outer.axis_moving) == (False, "DriveUnreachable", True)
    assert first == StopOutcome("first opened", "instrument", True)
    assert stops.axis_moving and stops.failures == (inner, outer)
    with pytest.raises(AttributeError):      # frozen: an outcome is a record
        inner.ok = True  # type: ignore[misc]


def test_a_base_exception_in_a_stop_is_raised_after_the_others_ran() -> None:
    ran: list[str] = []
    stops = Stops()
    stops.add("last", lambda: ran.append("last"), "twin")

    def leave() -> None:
        raise SystemExit(9)

    stops.add("exits", leave, "worker")
    with stops.collecting():                  # inside a child registry too
        child = Stops.child("the instruments")
    child.add("first", functools.partial(ran.append, "first"), "instrument")
    child.add("child exits", leave, "instrument")
    with pytest.raises(SystemExit):
        stops.run()
    assert ran == ["first", "last"]
    assert [(o.what, o.ok) for o in stops.outcomes] == [
        ("child exits", False), ("first", True), ("exits", False), ("last", True)]


def test_a_registry_made_while_another_collects_runs_in_its_place() -> None:
    ran: list[str] = []
    session = Stops()
    session.add("twins", lambda: ran.append("twins"), "twin")
    with session.collecting():
        child = Stops.child("the instruments", "instrument")
    child.add("counter", lambda: ran.append("counter"), "instrument")
    child.add("drive", lambda: ran.append("drive"), "axis")
    session.add("worker", lambda: ran.append("worker"), "worker")
    assert Stops.child("not collected").run() == ()   # outside: a registry of its own
    child.record(attempt("early safe stop", lambda: None, "axis"))
    session.run()
    assert ran == ["worker", "drive", "counter", "twins"]
    assert [o.what for o in session.outcomes] == [
        "worker", "early safe stop", "drive", "counter", "twins"]


def test_a_resource_made_deep_in_a_kind_registers_with_the_command() -> None:
    ran: list[str] = []
    register("alone", functools.partial(ran.append, "alone"), "worker")  # none collecting
    command = Stops()
    with command.collecting():
        register("hashing", functools.partial(ran.append, "hashing"), "worker")
    assert [o.what for o in command.run()] == ["hashing"] and ran == ["hashing"]


def test_stops_registered_from_threads_all_run_once() -> None:
    counts: dict[int, int] = {}
    lock = threading.Lock()
    stops = Stops()

    def bump(i: int) -> None:
        with lock:
            counts[i] = counts.get(i, 0) + 1

    def register(base: int) -> None:
        for i in range(base, base + 200):
            stops.add(f"stop {i}", functools.partial(bump, i), "twin")

    threads = [threading.Thread(target=register, args=(k * 200,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    runners = [threading.Thread(target=stops.run) for _ in range(3)]
    for t in runners:
        t.start()
    for t in runners:
        t.join()
    assert counts == dict.fromkeys(range(800), 1)


# -- every open/start registers its stop (an AST check) -----------------------------------

#: the files that open what a command must make safe (axes, twins, workers, servers,
#: instruments); drivers/ and sims/ define those resources, these open them
STOP_PATH_FILES = ("bench/core/instruments.py", "bench/core/simbench.py",
                   "bench/core/engine.py", "bench/app/session.py", "bench/app/devices.py",
                   "bench/app/simserve.py", "procedures/rate_ladder/kind.py",
                   "procedures/drift_pulse/kind.py")
OPENS = re.compile(r"(^|\.)(open|start)(_\w+)?$")
#: how a stop is registered: Stops.add/enter/adopt, Bench.enter/callback/log, SimBench.add
REGISTERS = {"add", "enter", "adopt", "callback", "enter_context"}
#: opens that register by other means, each with its reason
NOT_RESOURCES = {
    r"\.start_clock$": "the clock is paused by the simulated bench's first registered stop",
    r"^self\.clock\.start$": "the same clock (SimBench.start_clock)",
    r"^open_console$": "the console is closed by the session before its stops run",
    r"^(kind|self\.kind|procedure_kind\(cfg\.kind\))\.steps\.(start_sim|open_bench)$":
        "they make a SimBench / Bench whose registry joins the collecting one as it is "
        "made (Stops.child; checked by test_bench_and_simbench_join_the_collecting_registry)",
    r"^sim\.start$": "SimBench.start registers each twin as it starts it (checked here)",
    r"^self\.start$": "AnalysisWorker.submit starting itself: the engine registers the "
                      "worker's stop when it starts it",
    r"^threading\.Thread\(.*\)\.start$": "the worker process's parent watch: a daemon "
                                         "thread that ends with that process",
}


def _registration_names(fn: ast.AST) -> list[tuple[int, set[str]]]:
    """(line, the source of every name and attribute in its arguments) per registration."""
    out = []
    for node in ast.walk(fn):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                and node.func.attr in REGISTERS:
            names = {ast.unparse(n) for a in [*node.args, *(k.value for k in node.keywords)]
                     for n in ast.walk(a) if isinstance(n, ast.Name | ast.Attribute)}
            out.append((node.lineno, names))
    return out


def unregistered_opens(source: str, filename: str = "<source>") -> list[str]:
    """Each call of an `open*`/`start*` whose stop is not registered in the same function:
    inside a registration's arguments, passed a registry (`bench`, `stops`), or its
    result (or receiver) named in a registration that follows."""
    tree = ast.parse(source, filename)
    found: list[str] = []
    for fn in ast.walk(tree):
        if not isinstance(fn, ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        regs = _registration_names(fn)
        inside = {id(n) for node in ast.walk(fn) if isinstance(node, ast.Call)
                  and isinstance(node.func, ast.Attribute) and node.func.attr in REGISTERS
                  for a in node.args for n in ast.walk(a)}
        inside |= {id(n) for node in ast.walk(fn) if isinstance(node, ast.With)
                   for item in node.items for n in ast.walk(item.context_expr)}
        bound: dict[int, set[str]] = {}
        for node in ast.walk(fn):
            if isinstance(node, ast.Assign) and isinstance(node.value, ast.Call):
                targets = {ast.unparse(n) for t in node.targets for n in ast.walk(t)
                           if isinstance(n, ast.Name | ast.Attribute)}
                bound[id(node.value)] = targets
            elif isinstance(node, ast.Assign):   # x = Thing(port=y.start()): y's own
                for t in node.targets:
                    for call in ast.walk(node.value):
                        bound.setdefault(id(call), set()).update(
                            ast.unparse(n) for n in ast.walk(t) if isinstance(n, ast.Name))
        for call in ast.walk(fn):
            if not isinstance(call, ast.Call):
                continue
            name = ast.unparse(call.func)
            if not OPENS.search(name) or any(re.search(p, name) for p in NOT_RESOURCES):
                continue
            if id(call) in inside:
                continue
            if any(isinstance(a, ast.Name) and a.id in ("bench", "stops")
                   for a in call.args):
                continue                          # it registers on the registry it is given
            mine = set(bound.get(id(call), set()))
            if isinstance(call.func, ast.Attribute):
                mine.add(ast.unparse(call.func.value))   # the receiver: fg.open(), x.start()
            if any(line >= call.lineno and (mine & names or any(
                    n.startswith(f"{m}.") for m in mine for n in names))
                   for line, names in regs):
                continue
            found.append(f"{filename}:{call.lineno}: {name}(...) registers no stop")
    return found


def test_every_open_and_start_registers_its_stop() -> None:
    problems = [p for f in STOP_PATH_FILES
                for p in unregistered_opens((ROOT / f).read_text(), f)]
    assert problems == []


def test_the_check_catches_a_planted_open_without_its_stop() -> None:
    planted = '''
def serve_buses(stops, buses):
    server = SocketcandServer(buses)
    port = server.start()
    drive = Axis.open("outer")
    return port, drive
'''
    found = unregistered_opens(planted)
    assert [f.split(": ", 1)[1] for f in found] == [
        "server.start(...) registers no stop", "Axis.open(...) registers no stop"]
    fixed = planted.replace("    return", "    stops.add('server', server.stop, 'server')\n"
                                         "    stops.enter(drive, 'outer', 'axis')\n    return")
    assert unregistered_opens(fixed) == []


def test_bench_and_simbench_join_the_collecting_registry() -> None:
    for path, cls in (("bench/core/instruments.py", "Bench"),
                      ("bench/core/simbench.py", "SimBench")):
        tree = ast.parse((ROOT / path).read_text())
        init = next(n for c in ast.walk(tree) if isinstance(c, ast.ClassDef)
                    and c.name == cls for n in c.body
                    if isinstance(n, ast.FunctionDef) and n.name == "__init__")
        calls = {ast.unparse(n.func) for n in ast.walk(init) if isinstance(n, ast.Call)}
        assert "Stops.child" in calls, path


# -- a real session on the twins ----------------------------------------------------------

@pytest.mark.timeout(240)
def test_a_faulted_drive_ends_at_rest_and_the_outcomes_say_so(tmp_path: Path) -> None:
    cfg = load_config(_procedure(tmp_path))
    run = RunDir.create(tmp_path / "runs", cfg.procedure_path, cfg.stand_path)
    seen: dict[str, Any] = {}

    def hook(sim: Any) -> None:
        seen["sim"] = sim
        when_step_starts(run, lambda e: e.get("action") == "settle",
                         lambda: sim.twins["outer.drive"].inject(OVER_TEMPERATURE),
                         delay_s=0.02)

    session = RunSession(cfg, run, yes=True, on_sim_started=hook)
    assert session.run() == EXIT_ABORTED
    sim = seen["sim"]
    assert sim.stand.axes["outer"].commanded_rate_at(sim.clock.now() + 3600.0) == 0.0
    outcomes = session.stops.outcomes
    by_what = {o.what: o for o in outcomes}
    # the engine's safe stop first, then the registry, last opened first
    safe = by_what["safe stop: outer"]
    assert (safe.resource, safe.ok, safe.axis_moving) == ("axis", True, False)
    order = [o.what for o in outcomes]
    worker = order.index("the analysis worker")
    drive = next(i for i, o in enumerate(outcomes) if o.resource == "axis" and i > worker)
    twin = order.index("outer drive twin")
    assert order.index("safe stop: outer") < worker < drive < twin, order
    assert all(o.ok for o in outcomes), session.stops.failures
    assert not session.stops.axis_moving and session.later == []
    exit_event = [e for e in journal_lines(run) if e["event"] == "exit"][-1]
    assert exit_event["later"] == [] and "drive fault" in exit_event["cause"], exit_event
    assert order.count("the analysis worker") == order.count("outer") == 1
    # run again: no stop runs twice (what it returns is only the exit event's journaling,
    # recorded after the stops ran)
    assert [o.what for o in session.stops.run()] == ["journaling the exit event"]
    assert session.stops.outcomes == outcomes


@pytest.mark.timeout(240)
def test_a_silent_drive_is_an_outcome_whose_axis_may_be_moving(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The drive's heartbeat stops mid-run: the drive cannot be told to stop, and the
    session knows it from the outcome's field, not from the words of its message."""
    _hear_silence_sooner(monkeypatch)
    cfg = load_config(_procedure(tmp_path, SLOW_CLOCK))
    run = RunDir.create(tmp_path / "runs", cfg.procedure_path, cfg.stand_path)
    seen: dict[str, Any] = {}

    def hook(sim: Any) -> None:
        seen["sim"] = sim
        when_step_starts(run, lambda e: e.get("action") == "settle",
                         sim.twins["outer.drive"].silence_heartbeat, delay_s=0.02)

    session = RunSession(cfg, run, yes=True, on_sim_started=hook)
    assert session.run() == EXIT_ABORTED
    moving = [o for o in session.stops.outcomes if o.axis_moving]
    assert [(o.resource, o.ok, o.error_type) for o in moving] == [
        ("axis", False, "DriveUnreachable")], session.stops.outcomes
    assert session.stops.axis_moving
    sim = seen["sim"]     # the drive's own watchdog stopped the table
    assert sim.twins["outer.drive"].watchdog_trips
    assert sim.stand.axes["outer"].commanded_rate_at(sim.clock.now() + 3600.0) == 0.0
