"""The demo with its certificate, each run a whole process (issue 62; run on demand).

    python benchmarks/bench_demo.py [--repeat 3] [--procedure configs/procedures/demo.yaml]
                                    [--figure-workers N]

Runs `bench run PROCEDURE --yes --out FRESH` --repeat times, each in a fresh runs folder
with an empty HOME and XDG_CACHE_HOME (so matplotlib builds its font cache, as on a fresh
machine), and prints each run's wall and CPU seconds (the child's user + system time) and
the certificate's share, from the run directory's files: result.json is written before the
certificate, certificate.html and .pdf after it, certificate.dcc.xml last, so

- certificate: the last of certificate.html/.pdf less result.json's modification time
  (the records' history and assurance, the document, its figures, PDF and HTML);
- DCC: certificate.dcc.xml less that.

Each run's wall time is also split into its phases, from events.jsonl's times and the
files' (so a change can be put where it acts): start-up (the process's start to the
plan event: interpreter, imports, the records' due check, the twins started and the
instruments opened), measuring (plan to completed: the co-simulation, with the last
pair's analysis), analysis (to result.json), records (to assurance.json: the history
section and the control status), the certificate, the DCC, and exit (the DCC to the
process's end: registration and the interpreter's teardown). The load average beside
each run says how busy the machine was.

Then the medians, against the goal of issue 62: the demo and its certificate within 10 s
of wall time (on an idle machine: the load average is printed first). --figure-workers
sets BENCH_FIGURE_WORKERS for the runs (0: every figure drawn in turn, in the bench's
process; bench/app/certificate/figures.py), to compare.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
GOAL_S = 10.0


def bench_exe() -> list[str]:
    """The installed console script beside this interpreter, else `python -m bench`."""
    script = Path(sys.executable).parent / "bench"
    return [str(script)] if script.is_file() else [sys.executable, "-m", "bench"]


def run_once(procedure: Path, workers: int | None) -> dict[str, float]:
    """One `bench run` in fresh folders: wall, CPU, certificate and DCC seconds."""
    with tempfile.TemporaryDirectory(prefix="bench-demo-") as tmp:
        home, cache, out = (Path(tmp) / n for n in ("home", "cache", "runs"))
        home.mkdir()
        cache.mkdir()
        env = {**os.environ, "HOME": str(home), "XDG_CACHE_HOME": str(cache)}
        env.pop("MPLCONFIGDIR", None)
        if workers is not None:
            env["BENCH_FIGURE_WORKERS"] = str(workers)
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        started = time.time()
        t0 = time.perf_counter()
        r = subprocess.run([*bench_exe(), "run", str(procedure), "--yes", "--out", str(out)],
                           cwd=ROOT, capture_output=True, text=True, env=env, check=False)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        lines = r.stdout.strip().splitlines()
        run_dir = Path(lines[-1]) if lines else out
        files = {n: run_dir / n for n in ("result.json", "certificate.html",
                                          "certificate.pdf", "certificate.dcc.xml")}
        missing = [n for n, p in files.items() if not p.is_file()]
        if r.returncode not in (0, 1) or missing:
            raise SystemExit(f"bench run {procedure}: exit {r.returncode}, missing {missing}\n"
                             f"{r.stderr[-3000:]}")
        mtime = {n: p.stat().st_mtime for n, p in files.items()}
        rendered = max(mtime["certificate.html"], mtime["certificate.pdf"])
        at = event_times(run_dir / "events.jsonl")
        assured = run_dir / "assurance.json"
        records = assured.stat().st_mtime if assured.is_file() else mtime["result.json"]
        return {"wall": wall,
                "cpu": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
                "certificate": rendered - mtime["result.json"],
                "dcc": mtime["certificate.dcc.xml"] - rendered,
                "start-up": at["plan"] - started,
                "measuring": at["completed"] - at["plan"],
                "analysis": mtime["result.json"] - at["completed"],
                "records": records - mtime["result.json"],
                "exit": started + wall - mtime["certificate.dcc.xml"],
                "load": os.getloadavg()[0]}


PHASES = ("start-up", "measuring", "analysis", "records", "certificate", "dcc", "exit")


def event_times(events: Path) -> dict[str, float]:
    """The epoch time of the first plan and completed events of a run's journal."""
    at: dict[str, float] = {}
    for line in events.read_text(encoding="utf-8").splitlines():
        rec = json.loads(line)
        name = rec.get("event")
        if name in ("plan", "completed") and name not in at:
            at[name] = dt.datetime.fromisoformat(rec["utc"]).timestamp()
    return at


def phases(m: dict[str, float]) -> str:
    return ", ".join(f"{k} {m[k]:.2f}" for k in PHASES)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--procedure", type=Path, default=ROOT / "configs/procedures/demo.yaml")
    ap.add_argument("--figure-workers", type=int, default=None,
                    help="BENCH_FIGURE_WORKERS for the runs (default: the bench's own)")
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} (1 min), {os.cpu_count()} processors; "
          f"{args.repeat} runs of {args.procedure.name}")
    runs = []
    for i in range(args.repeat):
        m = run_once(args.procedure.resolve(), args.figure_workers)
        runs.append(m)
        print(f"  run {i + 1}: wall {m['wall']:.2f} s, cpu {m['cpu']:.2f} s, certificate "
              f"{m['certificate']:.2f} s ({m['certificate'] / m['wall']:.0%} of wall), "
              f"DCC {m['dcc']:.2f} s; load {m['load']:.2f}\n"
              f"         phases (s): {phases(m)}", flush=True)
    med = {k: statistics.median(m[k] for m in runs) for k in runs[0]}
    print(f"median: wall {med['wall']:.2f} s (goal <= {GOAL_S:g} s: "
          f"{'met' if med['wall'] <= GOAL_S else 'not met'}), cpu {med['cpu']:.2f} s, "
          f"certificate {med['certificate']:.2f} s ({med['certificate'] / med['wall']:.0%} "
          f"of wall), DCC {med['dcc']:.2f} s\n"
          f"        phases (s): {phases(med)}")


if __name__ == "__main__":
    main()
