"""A sustained FOG stream over the pty: 5 kHz for 60 s of stand time, with zero loss.

    /work/venv/bin/python benchmarks/bench_fog_stream.py [--rate-hz 5000] [--seconds 60]
                                                          [--speed 1] [--raw FILE]

The twin writes the simulated stand's FOG samples as KVH format A frames on a pty;
the driver reads them with pyserial, captures the raw bytes and decodes. At the end
every sample 0 .. N-1 must have arrived intact and equal the twin's float32 truth, and
the raw capture must decode to the same samples. Prints the real time taken, the
frame rate through the pty, and the driver's lag behind the stand clock.
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path

import numpy as np

from drivers.fog import Fog
from drivers.fog_formats import StreamDecoder
from sims.clock import VirtualClock
from sims.fog_twin import FogTwin
from sims.stand import AxisTruth, FogTruth, Harmonic, SimulatedStand, StandTruth


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate-hz", type=float, default=5000.0)
    ap.add_argument("--seconds", type=float, default=60.0, help="stand (virtual) seconds")
    ap.add_argument("--speed", type=float, default=1.0, help="virtual clock speed")
    ap.add_argument("--raw", type=Path, default=None, help="keep the capture here")
    args = ap.parse_args()

    clock = VirtualClock(args.speed, running=False)
    truth = StandTruth(seed=3, axes={"outer": AxisTruth(
        harmonics=(Harmonic(1, 8.6e-4, 40.0),), rate_noise_dps=1e-4,
        fog=FogTruth(scale=1.0003, bias_dps=0.002, noise_dps=0.01))})
    stand = SimulatedStand(truth, {"outer": args.rate_hz}, clock)
    n = int(args.seconds * args.rate_hz)
    tmp = tempfile.TemporaryDirectory()
    raw = args.raw or Path(tmp.name) / "fog.raw"
    lags = []
    cpu0 = resource.getrusage(resource.RUSAGE_SELF)
    twin = FogTwin(stand, "outer", keep_truth=True)  # before anything advances the axis
    stand.axes["outer"].command_rate(0.0, 100.0, 200.0)
    with twin, Fog(twin.path, rate_hz=args.rate_hz, raw_path=raw, clock=clock) as fog:
        clock.start()
        t0 = time.monotonic()
        next_report = 0.0
        while fog.end_index < n:
            time.sleep(0.05)
            now = clock.now()
            lags.append((now, now - (fog.end_index - 1) / args.rate_hz))
            if now >= next_report:
                print(f"  t = {now:7.1f} s  samples {fog.end_index:9d}  lag {lags[-1][1]:.4f} s",
                      flush=True)
                next_report += max(args.seconds / 6, 1.0)
            if time.monotonic() - t0 > 3 * args.seconds / args.speed + 30:
                print("gave up: the stream fell behind")
                return 1
        real_s = time.monotonic() - t0
        s = fog.samples(0, n)
        stats = fog.stats
    cpu1 = resource.getrusage(resource.RUSAGE_SELF)
    tr = twin.truth(0, n)
    cpu_s = (cpu1.ru_utime + cpu1.ru_stime) - (cpu0.ru_utime + cpu0.ru_stime)

    dec = StreamDecoder("kvh-a")
    parts = []
    with open(raw, "rb") as f:
        while chunk := f.read(1 << 20):
            parts.append(dec.feed(chunk))
    idx = np.concatenate([p.index for p in parts])
    z = np.concatenate([p.rates[:, 2] for p in parts]).astype(np.float64)
    keep = idx < n
    redecode_equal = bool(np.array_equal(idx[keep], np.arange(n))
                          and np.array_equal(z[keep], s.rate_dps))

    lost = int((~s.received).sum())
    equal = bool(np.array_equal(s.rate_dps, tr.rate_dps))
    print(f"rate {args.rate_hz:g} Hz, {args.seconds:g} s of stand time at speed "
          f"{args.speed:g}: {n} samples in {real_s:.1f} s real "
          f"({n / real_s / 1e3:.1f} k frames/s through the pty)")
    print(f"frames {stats.frames}, lost {lost}, crc_errors {stats.crc_errors}, "
          f"gaps {stats.gaps}, stalls {len(stats.stalls)}, bytes {stats.bytes}")
    print(f"rates equal to twin truth (float32): {equal}; raw capture re-decodes to the "
          f"same samples: {redecode_equal}")
    steady = np.array([g for t, g in lags if t >= 1.0])  # after the twin's start-up
    print(f"lag behind the stand clock after the first second: median "
          f"{np.median(steady) * 1e3:.1f} ms, max {np.max(steady) * 1e3:.1f} ms (stand time)")
    print(f"process CPU: {cpu_s:.1f} s for {real_s:.1f} s real "
          f"({100 * cpu_s / real_s:.0f} % of one core, twin and driver together)")
    ok = lost == 0 and stats.crc_errors == 0 and equal and redecode_equal
    print("PASS: zero loss" if ok else "FAIL")
    tmp.cleanup()
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
