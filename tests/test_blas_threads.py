"""The analysis's numbers do not follow the machine's core count (bench/analysis/blas.py).

OpenBLAS sums a large product's parts in an order that follows its thread count, so the
same record analysed with one BLAS thread and with four gave different last digits until
the analysis pinned BLAS to one thread. Each analysis here runs in its own process, its
BLAS started with the thread count in OPENBLAS_NUM_THREADS (as a bench on a machine of
that many cores would), over the same simulated pair (sims.stand's AxisModel, seed 7:
two halves of 3 turns at 10 deg/s, 1 kHz FOG, so each half's Gram product runs over full
65,536-sample chunks, the size OpenBLAS splits). The test compares every float of the
pair's result as text (repr): equal to the last bit. Four threads on a 2-core machine is
oversubscribed, not refused: OpenBLAS still splits the work four ways.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

SCRIPT = textwrap.dedent("""
    import dataclasses, sys
    import numpy as np
    sys.path.insert(0, sys.argv[1])
    from bench.analysis import CounterBudget, HalfRecord, analyze_pair
    from sims.stand import AxisModel, AxisTruth, FogTruth, Harmonic, Mains

    truth = AxisTruth(rate_bias_rel=2e-6, harmonics=(Harmonic(1, 8.6e-4, 40.0),),
                      mains=Mains(50.0, 2e-4, 0.0), rate_noise_dps=1e-4,
                      turn_jitter_s=27e-9,
                      fog=FogTruth(scale=1.0003, bias_dps=0.002, misalignment_deg=0.2,
                                   noise_dps=0.01, bias_drift_dps_per_h=0.001))
    rate_dps, turns, fog_hz = 10.0, 3, 1000.0
    model = AxisModel(truth, fog_hz, 7)
    fog = np.empty(int(2 * (turns + 2) * 36.0 * fog_hz + 30 * fog_hz))
    filled = [0]
    def listen(chunk):
        fog[chunk.n0:chunk.n0 + chunk.fog_dps.size] = chunk.fog_dps
        filled[0] = chunk.n0 + chunk.fog_dps.size
    model.listeners.append(listen)
    t, edges, signs = 0.0, [], []
    for sign in (1, -1):
        seg = model.command_rate(t, sign * rate_dps, 10.0)
        t_ok = seg.t_end_s + 0.5
        t_end = t_ok + (turns + 1.5) * 36.0
        model.advance_to(t_end)
        zm = model.zero_marks(t_ok, t_end)
        edges.append(zm.t_edge_s[:turns + 1].copy())
        signs.append(sign)
        t = float(zm.t_edge_s[turns]) + 1.8
    model.advance_to(t + 1.0)
    f = fog[:filled[0]]
    halves = [HalfRecord(s, e, np.arange(f.size) / fog_hz, f)
              for s, e in zip(signs, edges, strict=True)]
    res = analyze_pair(halves, rate_dps, fog_rate_hz=fog_hz,
                       counter_budget=CounterBudget(trigger_jitter_s=27e-9))
    from threadpoolctl import threadpool_info
    print([i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"])
    def floats(x, path="r"):
        if dataclasses.is_dataclass(x) and not isinstance(x, type):
            for f in dataclasses.fields(x):
                yield from floats(getattr(x, f.name), path + "." + f.name)
        elif isinstance(x, (list, tuple)):
            for i, v in enumerate(x):
                yield from floats(v, f"{path}[{i}]")
        elif isinstance(x, dict):
            for k, v in x.items():
                yield from floats(v, f"{path}[{k!r}]")
        elif isinstance(x, np.ndarray):
            yield path, x.tobytes().hex()
        elif isinstance(x, float):
            yield path, repr(x)
    for path, text in floats(res):
        print(path, text)
""")


def _analyse(threads: int) -> list[str]:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": str(threads)}
    r = subprocess.run([sys.executable, "-c", SCRIPT, str(ROOT)], env=env,
                       capture_output=True, text=True, timeout=240)
    assert r.returncode == 0, r.stderr
    return r.stdout.splitlines()


def test_one_blas_thread_and_four_give_the_same_result_to_the_last_bit() -> None:
    one, four = _analyse(1), _analyse(4)
    # the pin held: each BLAS loaded (numpy's, scipy's) ran on one thread in both processes
    assert set(eval(one[0])) == set(eval(four[0])) == {1}, (one[0], four[0])
    assert len(one) > 50, one[:5]   # the pair's figures, not an empty result
    differing = [(a, b) for a, b in zip(one, four, strict=True) if a != b]
    assert not differing, differing[:5]
