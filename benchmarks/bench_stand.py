"""How fast the simulated stand generates a record (run on demand, not in CI).

    python benchmarks/bench_stand.py

The issue's goal: 18 M FOG samples (5 turns at 0.1 deg/s, 1 kHz) in a few seconds.
"""

from __future__ import annotations

import resource
import time

from sims.stand import AxisModel, AxisTruth, FogTruth, Harmonic, Mains


def main() -> None:
    truth = AxisTruth(rate_bias_rel=2e-6, harmonics=(Harmonic(1, 8.6e-4, 40.0),),
                      mains=Mains(50.0, 2e-4), rate_noise_dps=1e-4, turn_jitter_s=27e-9,
                      fog=FogTruth(1.0003, 0.002, 0.2, 0.01, 0.001))
    ax = AxisModel(truth, 1000.0, seed=1)
    n = [0]
    ax.listeners.append(lambda c: n.__setitem__(0, n[0] + c.fog_dps.size))
    ax.command_rate(0.0, 0.1, 200.0)
    t0 = time.perf_counter()
    ax.advance_to(18_000.0)
    dt = time.perf_counter() - t0
    peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"samples: {n[0]:,}  time: {dt:.2f} s  rate: {n[0] / dt / 1e6:.1f} M samples/s  "
          f"zero marks: {ax.zero_marks().t_true_s.size}  peak RSS: {peak_mib:.0f} MiB")


if __name__ == "__main__":
    main()
