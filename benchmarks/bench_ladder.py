"""Benchmark: a whole ladder on the twins, wall time and peak memory (run on demand).

    /work/venv/bin/python benchmarks/bench_ladder.py [--procedure configs/procedures/paper-ladder.yaml]
        [--fog-hz 5000] [--axes outer] [--rates 0.1] [--turns-scale 2] [--out DIR]

Runs `bench run PROCEDURE --yes` as a new user would (the shipped stand, `clock_speed:
max`), and samples the resident memory of the whole process tree (the bench, its
analysis worker) every 0.2 s with psutil. Options rewrite copies of the procedure and
stand: the FOG's rate, a subset of axes or rates, more turns (a longer ladder). Prints
one line: bench time, wall time, peak RSS of the tree, frames lost, exit status.
Goals (issue 14, this 2-core machine): paper ladder <= 5 min wall; peak RSS <= 1 GB at
1 kHz and <= 1.5 GB at 5 kHz, the same for a ladder twice as long; 0 frames lost.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil
import yaml

ROOT = Path(__file__).resolve().parent.parent


def tree_rss_bytes(proc: psutil.Process) -> int:
    total = 0
    for p in [proc, *proc.children(recursive=True)]:
        try:
            total += p.memory_info().rss
        except (psutil.NoSuchProcess, psutil.AccessDenied):
            pass
    return total


def prepare(args: argparse.Namespace, tmp: Path) -> Path:
    proc_path = (ROOT / args.procedure).resolve()
    proc = yaml.safe_load(proc_path.read_text())
    stand_path = (proc_path.parent / proc["stand"]).resolve()
    stand = yaml.safe_load(stand_path.read_text())
    if args.fog_hz:
        for ax in stand["axes"].values():
            if ax.get("fog"):
                ax["fog"]["rate_hz"] = args.fog_hz
    if args.axes:
        proc["axes"] = {a: s for a, s in proc["axes"].items() if a in args.axes}
    if args.rates:
        for s in proc["axes"].values():
            s["rates_dps"] = [r for r in s["rates_dps"] if r in args.rates]
    if args.turns_scale != 1:
        proc["turns"] = int(proc.get("turns", 5) * args.turns_scale)
        proc["static_record_s"] = proc.get("static_record_s", 60) * args.turns_scale
    (tmp / "stand.yaml").write_text(yaml.safe_dump(stand, sort_keys=False))
    proc["stand"] = str(tmp / "stand.yaml")
    out = tmp / "procedure.yaml"
    out.write_text(yaml.safe_dump(proc, sort_keys=False))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--procedure", default="configs/procedures/paper-ladder.yaml")
    ap.add_argument("--fog-hz", type=float, default=None, help="every FOG's rate_hz")
    ap.add_argument("--axes", nargs="*", default=None)
    ap.add_argument("--rates", nargs="*", type=float, default=None)
    ap.add_argument("--turns-scale", type=float, default=1.0, help="2: a ladder twice as long")
    ap.add_argument("--out", type=Path, default=None, help="keep the run directory here")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-ladder-") as tmp_s:
        tmp = Path(tmp_s)
        procedure = prepare(args, tmp)
        out = args.out or tmp / "runs"
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        t0 = time.monotonic()
        p = subprocess.Popen([sys.executable, "-m", "bench", "run", str(procedure), "--yes",
                              "--out", str(out)], cwd=ROOT, env=env, text=True,
                             stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        ps = psutil.Process(p.pid)
        peak = 0
        while p.poll() is None:
            peak = max(peak, tree_rss_bytes(ps))
            time.sleep(0.2)
        wall = time.monotonic() - t0
        stdout = p.stdout.read() if p.stdout else ""
        run_dir = Path(stdout.strip().splitlines()[-1]) if stdout.strip() else None
        bench_s = lost = load = None
        if run_dir and (run_dir / "events.jsonl").exists():
            ev = [json.loads(x) for x in (run_dir / "events.jsonl").read_text().splitlines()]
            done = [e for e in ev if e["event"] == "completed"]
            bench_s = done[-1]["t_s"] if done else None
            lost = sum(int(e.get("fog_lost", 0)) for e in ev if e["event"] == "acquire")
        load = os.getloadavg()[0]
        fog = f"{args.fog_hz:g} Hz" if args.fog_hz else "stand's rate"
        print(f"{Path(args.procedure).stem} (FOG {fog}, axes {args.axes or 'all'}, rates "
              f"{args.rates or 'all'}, turns x{args.turns_scale:g}): bench time "
              f"{bench_s if bench_s is None else round(bench_s)} s, wall {wall:.0f} s, "
              f"peak RSS of the process tree {peak / 2**20:.0f} MB, FOG frames lost {lost}, "
              f"exit {p.returncode}, load average at the end {load:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
