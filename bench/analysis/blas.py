"""One BLAS thread for the analysis, whatever the machine.

OpenBLAS splits a large product (the Gram matrix of docs/method.md A4, 13 rows x 65,536
samples a chunk) over as many threads as the machine has cores, and each split sums in
another order: on 29 Nov 2026 the demo's result.json differed in 136 values (last digits,
up to 7e-14 relative) between one thread and two. A run's numbers must depend on its seed
and files alone (DEVELOPERS.md), so the analysis pins BLAS to one thread when it is
imported, before any product; on a 2-core bench with a co-simulation beside it, one thread
is also not slower.
threadpoolctl (scikit-learn's) finds the BLAS numpy loaded and sets its thread count for
the whole process; its cost is a fraction of a millisecond, paid once.
"""

from __future__ import annotations

import os
import threading

_pinned = False
_lock = threading.Lock()


def one_blas_thread() -> None:
    """Pin the process's BLAS to one thread (idempotent; safe from any thread).

    Called when bench.analysis is imported, before any product of the analysis: a pin at
    the first Gram product left the cross-calibration's products of a process's first
    pair on two threads, so `bench analyze` and the run (whose first looks run in another
    order) differed in a last digit. The BLAS already loaded (numpy's) is limited through
    threadpoolctl; one loaded later (scipy's) reads OPENBLAS_NUM_THREADS when it loads."""
    global _pinned
    if _pinned:
        return
    with _lock:
        if not _pinned:
            from threadpoolctl import ThreadpoolController  # lazy: only runs that analyse

            os.environ["OPENBLAS_NUM_THREADS"] = "1"
            ThreadpoolController().limit(limits=1, user_api="blas")
            _pinned = True
