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

#: the files that take longest, about longest first, with the CPU seconds each took alone
#: (`-n 0`, setup and calls, the session's shared runs it made itself left out; measured on
#: a shared 2-core machine at load 2-10, 29 Nov 2026, before the suite's certificates drew
#: their figures in-process (pyproject.toml `figure_workers`): CI's fresh clone, with the
#: other worker beside it, takes 1.5-3 times as long): their order is what counts. The
#: determinism file comes second on purpose: it makes the session's demo and drift demo
#: runs, which later files read, and its loaded runs (two busy processes) then meet the
#: resume-truth runs on the other worker, which are on the co-simulation clock and so
#: indifferent to load. The files after test_impact_drift.py were measured by
#: tests/filetimes.py (CPU seconds, `-n 0`, load 11-15, 29 Nov): they come late in the
#: collection's order, where one of them could keep a worker busy while the other had
#: nothing left. The files marked `issue 62` were measured again by tests/filetimes.py
#: after that issue's suite changes (`-n 0`, load 12-19, 29 Nov; before them, the same way
#: at load 8-12: 112, 148 and ~49; test_station.py at load 7: 48 before, 43 after). The
#: three marked `CI's CPU s` (tests/filetimes.py in the fresh-clone CI of f16d6b2, 30 Nov:
#: 97, 35 and 35, test_register.py's with the session's demo run in it and before the
#: suite's cheap password hashes) had started in the collection's order, test_register.py
#: at 786 s of 931, the last long file of that run's tail. A
#: file not named here starts after these, in the collection's order;
#: tests/test_schedule.py checks that each name is a test file of the suite.
SLOW_FIRST: tuple[tuple[str, int], ...] = (
    ("test_resume_truth.py", 80),     # issue 62
    ("test_determinism.py", 105),
    ("test_fault_matrix.py", 120),    # issue 62
    ("test_control.py", 140),
    ("test_records.py", 127),
    ("test_impact_reissue.py", 110),   # five check runs, then three re-issues (issue 58)
    ("test_register.py", 75),        # CI's CPU s, see above
    ("test_run_e2e.py", 40),         # issue 62; the demo run left out
    ("test_station.py", 43),        # issue 62; and real-time waits: a 5x paced clock
    ("test_fleet.py", 53),
    ("test_document_control.py", 52),
    ("test_register_service.py", 50),
    ("test_impact.py", 45),
    ("test_lab_rule.py", 37),
    ("test_register_records.py", 35),   # CI's CPU s, see above
    ("test_run_record.py", 35),        # CI's CPU s, see above
    ("test_starter.py", 31),
    ("test_impact_drift.py", 25),
    ("test_station_signing.py", 22),
    ("test_station_tls.py", 20),
    ("test_stop_path.py", 28),
    ("test_validate_robust.py", 24),   # hypothesis's fuzzing of the YAML files
    ("test_session_lifecycle.py", 14),
    ("test_simserve.py", 10),
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
