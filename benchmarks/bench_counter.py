"""Benchmark: the counter driver against its twin over pyvisa-py TCPIP SOCKET (on demand).

    python benchmarks/bench_counter.py [--model keysight-53230a] [--edges 10000]

Reports (1) the round trip of a checked write (command + SYST:ERR?), (2) the arm-to-data
overhead of a short acquisition beyond its nominal span, (3) the time to fetch and
decode a long timestamp record, and the largest error of the edges against the stand's
truth. Goals: a checked write under 2 ms on loopback; overhead under 50 ms; a 10 000-edge
record fetched and decoded in under 1 s.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from drivers.counter import Counter  # noqa: E402
from drivers.counter_settings import CounterSettings  # noqa: E402
from sims.clock import VirtualClock  # noqa: E402
from sims.counter_twin import CounterTwin  # noqa: E402
from sims.stand import AxisTruth, SimulatedStand, StandTruth  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="keysight-53230a")
    ap.add_argument("--edges", type=int, default=10_000)
    args = ap.parse_args()

    def stand(speed: float) -> SimulatedStand:
        s = SimulatedStand(StandTruth(1, {"a": AxisTruth(turn_jitter_s=27e-9)}), {"a": 100.0},
                           VirtualClock(speed))
        s.axes["a"].command_rate(0.0, 360.0, 1e6)
        return s

    st = stand(200.0)
    with CounterTwin(st, "a", CounterSettings(resource="", model=args.model)) as twin, \
            Counter.open(twin.resource, args.model, st.clock, timeout_margin_s=1.0) as c:
        c.configure(level_v=2.5)
        n = 200
        t0 = time.perf_counter()
        for _ in range(n):
            c.send(c.words.input_level, level_v=2.5)
        print(f"checked write: {(time.perf_counter() - t0) / n * 1e3:.2f} ms")
        t0 = time.perf_counter()
        if c.supports_timestamps:
            c.acquire_edges(6, 1.0)
        else:
            c.acquire_periods(2, 1.0)
        took = time.perf_counter() - t0
        acq = c.last_acquisition
        print(f"short acquisition: {took * 1e3:.1f} ms for a nominal span of "
              f"{acq.span_real_s / 1.25 * 1e3:.1f} ms (worst case {acq.span_real_s * 1e3:.1f} ms)")

    if args.edges <= 0:
        return 0
    st = stand(2e4)  # 10 000 turns of 1 s in 0.5 s real
    with CounterTwin(st, "a", CounterSettings(resource="", model=args.model)) as twin, \
            Counter.open(twin.resource, args.model, st.clock, timeout_margin_s=2.0) as c:
        if not c.supports_timestamps:
            print("long record: skipped (no timestamps)")
            return 0
        c.configure(level_v=2.5)
        c.arm(args.edges, 1.0)
        st.clock.sleep(args.edges * 1.05 + 1.0)
        t0 = time.perf_counter()
        edges = c.fetch()
        took = time.perf_counter() - t0
        ax = st.axes["a"]
        ax.advance_to(st.clock.now())
        truth = ax.zero_marks(twin.acquisition.t_arm_s, np.inf).t_edge_s[:edges.size]
        err = np.max(np.abs(edges - truth))
        print(f"long record: {edges.size} edges fetched and decoded in {took * 1e3:.0f} ms; "
              f"max |edge - truth| {err * 1e12:.1f} ps (resolution "
              f"{c.profile.resolution_s * 1e12:g} ps)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
