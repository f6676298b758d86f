"""bench/core/engine.py AnalysisWorker: every thread of the worker process below the bench.

A real spawned worker process; the job wakes its BLAS threads (a matrix product) and
reads every thread's priority from the kernel.
"""

from __future__ import annotations

import os
import sys
import threading
from typing import Any

import numpy as np
import pytest

from bench.core.engine import WORKER_NICE, AnalysisWorker


def _report() -> dict[str, Any]:
    """Run in the worker: a BLAS product first (it wakes the BLAS threads), then who is
    there and at which priority."""
    a = np.ones((64, 4096))
    _ = a @ a.T
    tids = [int(t) for t in os.listdir("/proc/self/task")]
    return {"nice": {tid: os.getpriority(os.PRIO_PROCESS, tid) for tid in tids}}


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="per-thread nice: Linux")
def test_every_worker_thread_runs_below_the_bench() -> None:
    bench_nice = os.getpriority(os.PRIO_PROCESS, 0)
    got: dict[str, Any] = {}
    done = threading.Event()

    def on_done(result: Any, error: BaseException | None) -> None:
        got["result"], got["error"] = result, error
        done.set()

    worker = AnalysisWorker()
    try:
        worker.submit(_report, on_done=on_done)
        assert done.wait(120), "the worker did not answer"
    finally:
        worker.close()
    assert got["error"] is None
    report = got["result"]
    assert len(report["nice"]) >= 2            # the job's thread and the parent watch
    low = min(bench_nice + WORKER_NICE, 19)
    assert all(n >= low for n in report["nice"].values()), report["nice"]
