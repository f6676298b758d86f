"""The order the suite's files start in under pytest-xdist (a plugin of the suite, named in
tests/conftest.py's `pytest_plugins`).

`--dist loadfile` (pyproject.toml) gives a worker whole files, the next file of the
collection each time the worker runs short of tests. The collection is in alphabetical
order, so a file of several minutes could start last and keep one worker busy long after
the other had finished. Here the files that take longest start first, longest first (the
longest-processing-time rule: the short files fill in the end, on whichever worker is
free), and every other file follows in its usual order. Within a file nothing moves: its
tests and its module fixtures run in file order, as in a one-process run, which keeps that
order untouched too (`-n 0`: no workers, no reordering).
"""

from __future__ import annotations

import pytest

#: the files that take longest, longest first, with the seconds a file took on one worker
#: beside the other (setup and calls, from `--durations` and per-file runs on a loaded
#: 2-core machine, 29 Nov 2026): their order is what counts, the seconds say why. A file
#: not named here starts after these, in the collection's order; tests/test_schedule.py
#: checks that each name is a test file of the suite.
SLOW_FIRST: tuple[tuple[str, int], ...] = (
    ("test_resume_truth.py", 470),
    ("test_determinism.py", 300),
    ("test_records.py", 250),
    ("test_control.py", 160),
    ("test_run_e2e.py", 120),
    ("test_document_control.py", 100),
    ("test_station.py", 90),
    ("test_station_tls.py", 70),
    ("test_fleet.py", 60),
)


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Under xdist (a worker process: `workerinput`), the files of SLOW_FIRST first, in its
    order; a stable sort, so each file's tests keep theirs. Every worker sorts the same
    collection the same way, as xdist requires."""
    if not hasattr(config, "workerinput"):
        return
    rank = {name: i for i, (name, _) in enumerate(SLOW_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))
