"""Decode throughput of the FOG frame decoder, in frames per second (goal >= 2 M/s).

    /work/venv/bin/python benchmarks/bench_fog_decode.py [--frames N] [--repeat R]

Three cases: a clean capture decoded whole; the same fed in 64 KiB pieces through the
StreamDecoder (what the live driver and `bench decode` do); and a dirty stream with
1 % of frames corrupted and a garbage burst every 1000 frames.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from drivers.fog_formats import KVH_A, StreamDecoder, decode


def clean_stream(n: int, seed: int = 0) -> bytes:
    rng = np.random.default_rng(seed)
    rates = rng.standard_normal((n, 3)).astype(np.float32)
    return KVH_A.encode(np.arange(n), rates, temperature=25).tobytes()


def dirty_stream(n: int, seed: int = 1) -> tuple[bytes, int]:
    rng = np.random.default_rng(seed)
    rows = KVH_A.encode(np.arange(n), rng.standard_normal((n, 3)).astype(np.float32)).copy()
    bad = rng.choice(n, n // 100, replace=False)
    rows[bad, 14] ^= 0x5A
    parts = []
    for k in range(0, n, 1000):
        parts.append(rows[k:k + 1000].tobytes())
        parts.append(rng.integers(0, 256, 200, dtype=np.uint8).tobytes())
    return b"".join(parts), n - bad.size


def best_of(repeat: int, fn) -> float:  # type: ignore[no-untyped-def]
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=2_000_000)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    n = args.frames
    raw = clean_stream(n)

    frames, _, stats = decode(raw, "kvh-a")
    assert stats.frames == n and stats.crc_errors == 0 and stats.gaps == 0
    t = best_of(args.repeat, lambda: decode(raw, "kvh-a"))
    print(f"clean, whole buffer ({len(raw) / 1e6:.0f} MB): {n / t / 1e6:6.2f} M frames/s")

    def chunked() -> None:
        dec = StreamDecoder("kvh-a")
        view = memoryview(raw)
        for i in range(0, len(raw), 1 << 16):
            dec.feed(view[i:i + (1 << 16)])
        assert dec.frames == n
    t = best_of(args.repeat, chunked)
    print(f"clean, 64 KiB pieces:            {n / t / 1e6:6.2f} M frames/s")

    dirty, intact = dirty_stream(n)
    _, _, s = decode(dirty, "kvh-a")
    assert s.frames == intact and s.crc_errors == n - intact
    t = best_of(args.repeat, lambda: decode(dirty, "kvh-a"))
    print(f"dirty (1 % corrupt, garbage):     {n / t / 1e6:6.2f} M frames/s "
          f"({s.crc_errors} CRC errors, {s.gaps} gaps found)")


if __name__ == "__main__":
    main()
