"""The suite's file order under xdist (tests/schedule.py): the slow files named there exist,
start first in the order given, and no file's tests change their order."""

from __future__ import annotations

import types
from pathlib import Path

from tests import schedule

TESTS = Path(__file__).resolve().parent


def test_each_slow_file_named_is_a_test_file_of_the_suite_and_named_once() -> None:
    names = [name for name, _ in schedule.SLOW_FIRST]
    assert len(set(names)) == len(names), names
    missing = [name for name in names if not (TESTS / name).is_file()]
    assert not missing, f"tests/schedule.py names files the suite no longer has: {missing}"
    assert all(seconds > 0 for _, seconds in schedule.SLOW_FIRST), schedule.SLOW_FIRST


def _items(*ids: str) -> list[types.SimpleNamespace]:
    return [types.SimpleNamespace(path=TESTS / i.split("::")[0], nodeid=i) for i in ids]


def test_workers_start_the_slow_files_first_and_keep_each_files_order() -> None:
    first, second = (name for name, _ in schedule.SLOW_FIRST[:2])
    ids = ["test_a.py::x", f"{second}::c", "test_a.py::y", f"{first}::b", f"{second}::a",
           "test_b.py::z", f"{first}::a"]
    worker = types.SimpleNamespace(workerinput={"workerid": "gw0"})
    items = _items(*ids)
    schedule.pytest_collection_modifyitems(worker, items)  # type: ignore[arg-type]
    assert [i.nodeid for i in items] == [f"{first}::b", f"{first}::a", f"{second}::c",
                                         f"{second}::a", "test_a.py::x", "test_a.py::y",
                                         "test_b.py::z"]
    alone = _items(*ids)                       # one process (-n 0): the order as collected
    schedule.pytest_collection_modifyitems(types.SimpleNamespace(), alone)  # type: ignore[arg-type]
    assert [i.nodeid for i in alone] == ids
