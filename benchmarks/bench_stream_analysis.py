"""Benchmark: a 5 kHz FOG streams while an 18 M-sample pair is analysed (run on demand).

    /work/venv/bin/python benchmarks/bench_stream_analysis.py [--rate-hz 5000] [--speed 1]
        [--samples 18e6] [--in-process]

The bench's acquisition threads in one process, as in a run: the FOG twin writing KVH
frames on a pty at `rate-hz` on a clock at `speed` (1: real time, as on hardware), the
FOG driver reading, capturing and decoding them, and a CANopen-style heartbeat producer
(drivers.heartbeat, every 50 ms). Meanwhile an 18 M-sample pair is simulated and analysed
as the rate ladder does it: in the analysis worker process (bench.core.engine.AnalysisWorker),
or with --in-process in a thread of the bench process (how it was before issue 14).
Prints one line: frames lost or broken, the FOG reader's worst lag behind the stand
clock (real ms: on a real port, what the UART and kernel buffers must hold), the longest
heartbeat gap (ms, period 50), and how long the analysis took.
Goal: 0 frames lost and no heartbeat missed (a gap under 2 periods) while analysing.
"""

from __future__ import annotations

import argparse
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from bench.core.engine import AnalysisWorker
from drivers.fog import Fog
from drivers.heartbeat import HeartbeatProducer
from sims.clock import VirtualClock
from sims.fog_twin import FogTwin
from sims.stand import AxisTruth, FogTruth, SimulatedStand, StandTruth

HEARTBEAT_S = 0.05


def analyse_pair(samples: float) -> str:
    """Simulate a +/- pair of about `samples` FOG samples at 1 kHz and analyse it
    (0: no analysis, 20 s of idling: the machine's own noise, for comparison)."""
    if not samples:
        time.sleep(20.0)
        return "no analysis"
    from bench.analysis import CounterBudget, analyze_pair
    from benchmarks.bench_analysis import simulate

    turns = max(2, round(samples / 1000.0 / 360.0 / 2))  # 1 deg/s: 360 s a turn
    halves = simulate(1.0, turns, "+-", 1000.0, seed=7)
    res = analyze_pair(halves, 1.0, fog_rate_hz=1000.0,
                       counter_budget=CounterBudget(trigger_jitter_s=27e-9))
    return f"{halves[0].fog_dps.size / 1e6:.1f} M samples, k = {res.pair.k:.7f}"


class Gaps:
    """The heartbeat producer's sender: remembers the longest gap between sends."""

    def __init__(self) -> None:
        self.last: float | None = None
        self.max_gap_s = 0.0

    def send_message(self, can_id: int, data: bytes, remote: bool = False) -> None:
        now = time.monotonic()
        if self.last is not None:
            self.max_gap_s = max(self.max_gap_s, now - self.last)
        self.last = now


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate-hz", type=float, default=5000.0)
    ap.add_argument("--speed", type=float, default=1.0, help="stand clock speed")
    ap.add_argument("--samples", type=float, default=18e6)
    ap.add_argument("--in-process", action="store_true", help="analyse in a thread instead")
    args = ap.parse_args()

    clock = VirtualClock(args.speed, running=False)
    truth = StandTruth(seed=3, axes={"outer": AxisTruth(rate_noise_dps=1e-4,
                                                        fog=FogTruth(noise_dps=0.01))})
    stand = SimulatedStand(truth, {"outer": args.rate_hz}, clock)
    twin = FogTwin(stand, "outer")
    stand.axes["outer"].command_rate(0.0, 10.0, 50.0)
    done = threading.Event()
    outcome: dict[str, Any] = {}

    def finished(result: Any, error: BaseException | None) -> None:
        outcome.update(result=result, error=error, t=time.monotonic())
        done.set()

    with tempfile.TemporaryDirectory() as tmp, twin:
        fog = Fog(twin.path or "", rate_hz=args.rate_hz, units="deg/s",
                  raw_path=Path(tmp) / "fog.raw", clock=clock, keep_samples=1 << 16)
        gaps = Gaps()
        beat = HeartbeatProducer(gaps, 0x701, b"\x05", HEARTBEAT_S)
        with fog:
            clock.start()
            beat.start()
            time.sleep(1.0)  # streaming before the analysis starts
            t0 = time.monotonic()
            worst_lag_s = 0.0
            if args.in_process:
                def run() -> None:
                    try:
                        finished(analyse_pair(args.samples), None)
                    except BaseException as e:  # noqa: BLE001 - reported below
                        finished(None, e)
                threading.Thread(target=run, daemon=True).start()
                worker = None
            else:
                worker = AnalysisWorker()
                worker.submit(analyse_pair, args.samples, on_done=finished)
            while not done.wait(0.01):
                worst_lag_s = max(worst_lag_s, fog.stats.lag_s)
            time.sleep(1.0)  # and after it
            beat.stop()
            if worker is not None:
                worker.close()
            st = fog.stats
        where = "a thread of the bench process" if args.in_process else "the worker process"
        print(f"{args.rate_hz:g} Hz FOG at clock speed {args.speed:g} while a pair is "
              f"analysed in {where} ({outcome.get('result') or outcome.get('error')}): "
              f"frames {st.frames}, lost or broken {st.lost_frames + st.crc_errors}, "
              f"worst reader lag {worst_lag_s / args.speed * 1000:.0f} ms real, longest "
              f"heartbeat gap {gaps.max_gap_s * 1000:.0f} ms (period "
              f"{HEARTBEAT_S * 1000:.0f}), analysis {outcome['t'] - t0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
