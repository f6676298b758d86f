"""Benchmark: the drift-pulse analysis and the platform twin (run on demand).

    python benchmarks/bench_drift_pulse.py [--cycles 10] [--rate-hz 2000] [--repeat 3]

Records the paper's case (latitude 70 deg, azimuth 80 deg; 5 s pulses; 4 timing cycles and
N cycles at 0 and 180 deg, two gyros) straight from the platform twin, then times
`analyze` on one core. Goals: the twin generates >= 2 M samples/s; the analysis handles
>= 1 M samples/s (a demo's 1 M samples in about a second), so `bench analyze` of a long
run stays interactive.
"""

from __future__ import annotations

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from procedures.drift_pulse import analysis as dp  # noqa: E402
from tests import drift_cycles  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--cycles", type=int, default=10)
    ap.add_argument("--rate-hz", type=float, default=2000.0)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    drift_cycles.FS_HZ = args.rate_hz
    truth = drift_cycles.paper_truth(angle_noise_arcsec=1.0, pulse_mismatch_rel=2e-6,
                                     pulse_jitter_s=1e-6, drift_random_walk_dph_per_rth=0.003)
    shape = dp.SHAPES["rectangular"]
    t0 = time.perf_counter()
    recs, _ = drift_cycles.record_cycles(truth, shape, cycles=args.cycles, timing_cycles=4)
    gen_s = time.perf_counter() - t0
    n = sum(r.u_v.size for rs in recs.values() for r in rs)
    best = float("inf")
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        res = dp.analyze(recs, shape, {"x": 2.0, "y": 2.0}, 70.0)
        best = min(best, time.perf_counter() - t0)
    print(f"samples: {n:,} in {sum(len(r) for r in recs.values())} cycle records")
    print(f"twin:     {gen_s:.2f} s, {n / gen_s / 1e6:.2f} M samples/s (goal >= 2)")
    print(f"analysis: {best:.2f} s, {n / best / 1e6:.2f} M samples/s (goal >= 1)")
    print(f"azimuth {res.azimuth_deg:.4f} +/- {res.azimuth_u_deg:.4f} deg")
    return 0


if __name__ == "__main__":
    sys.exit(main())
