"""A run's uid belongs to the run (issue 57, item 6): two benches that start the same
procedure on the same stand file in the same second write folders of the same name, and
still get distinct uids, which re-reading the run gives again; a run written before the
uid was kept in meta.json keeps the uid it was registered under."""

from __future__ import annotations

import datetime as dt
import json
import time
from pathlib import Path

from bench.app.fleet.sync import RunFacts
from bench.app.records.extract import run_uid
from bench.core import rundir_layout as layout
from bench.core.journal import RunDir
from tests.conftest import CONFIGS

PROCEDURE = CONFIGS / "procedures" / "demo.yaml"
STAND = CONFIGS / "stands" / "sim-two-axis.yaml"


def _same_second(tmp_path: Path) -> tuple[RunDir, RunDir]:
    """Two benches' runs created within one wall-clock second (retried at a second's
    edge), each in its own runs folder."""
    for _ in range(5):
        if dt.datetime.now().microsecond > 800_000:
            time.sleep(0.25)
        a = RunDir.create(tmp_path / "hall-1" / "runs", PROCEDURE, STAND)
        b = RunDir.create(tmp_path / "hall-2" / "runs", PROCEDURE, STAND)
        if a.path.name == b.path.name:
            return a, b
    raise AssertionError("could not create two runs within one second")


def test_two_benches_started_in_the_same_second_get_distinct_uids(tmp_path: Path) -> None:
    a, b = _same_second(tmp_path)
    assert a.path.name == b.path.name
    metas = [json.loads((r.path / layout.META).read_text()) for r in (a, b)]
    assert metas[0]["procedure_sha256"] == metas[1]["procedure_sha256"]
    assert metas[0]["stand_sha256"] == metas[1]["stand_sha256"]
    # even the creation stamps to the millisecond made equal: the uids still differ
    metas[1]["created_utc"] = metas[0]["created_utc"]
    (b.path / layout.META).write_text(json.dumps(metas[1]))
    uids = [run_uid(m, a.path.name) for m in metas]
    assert uids[0] != uids[1] and all(len(u) == 32 for u in uids)
    # what a bench delivers to the lab database is keyed by the same uid, again and again
    assert [RunFacts.of(r.path).uid for r in (a, b)] == uids
    assert [RunFacts.of(r.path).uid for r in (a, b)] == uids


def test_a_run_from_before_the_uid_keeps_its_registered_uid(tmp_path: Path) -> None:
    old = {"created_utc": "2026-01-02T03:04:05.678+00:00", "procedure_sha256": "a" * 64,
           "stand_sha256": "b" * 64}
    import hashlib
    expected = hashlib.sha256(("|".join((old["created_utc"], "a" * 64, "b" * 64))
                               + "|run-1").encode()).hexdigest()[:32]
    assert run_uid(old, "run-1") == expected
