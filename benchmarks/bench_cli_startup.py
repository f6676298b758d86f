"""Start-up time of the `bench` command, each case a whole process (issue 45; run on demand).

    python benchmarks/bench_cli_startup.py [--repeat 5] [--parse-only] [--no-bytecode-cache]
                                           [--imports N]

Times `bench --help`, `bench --version`, `bench validate --help` and `bench run --help`
(the parser alone: bench/app/cli.py imports a command's module only when it runs), then
`bench validate configs/procedures/demo.yaml` and `bench schema stand` (a command that
loads the configuration), each beside `python -c pass` in the same run. Each case runs
once to warm the file cache, then --repeat times; wall and CPU seconds (the child's user
+ system time, steadier than wall on a busy machine) as min and median.
Goal: the median wall time of each at most 0.4 s.

The bench runs as an installed package does, from compiled bytecode: the children write
and read theirs in a temporary folder (PYTHONPYCACHEPREFIX; the warm-up run compiles),
even where the environment says PYTHONDONTWRITEBYTECODE. --no-bytecode-cache keeps the
environment as it is (then, with PYTHONDONTWRITEBYTECODE, every run compiles every
module it imports: a few hundred milliseconds more). Whether this environment sets
PYTHONDONTWRITEBYTECODE is printed first (CI does not), with the load average: on a shared
machine, compare the cases of one run, not runs. --imports N: after each case, its N
heaviest imports (cumulative, from one run under PYTHONPROFILEIMPORTTIME), to find what a
command still loads.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
GOAL_S = 0.4


def bench_exe() -> list[str]:
    """The installed console script beside this interpreter, else `python -m bench`."""
    script = Path(sys.executable).parent / "bench"
    return [str(script)] if script.is_file() else [sys.executable, "-m", "bench"]


def cases(parse_only: bool) -> list[tuple[str, list[str]]]:
    bench = bench_exe()
    out = [("python -c pass", [sys.executable, "-c", "pass"]),
           ("bench --help", [*bench, "--help"]),
           ("bench --version", [*bench, "--version"]),
           ("bench validate --help", [*bench, "validate", "--help"]),
           ("bench run --help", [*bench, "run", "--help"])]
    if not parse_only:
        out += [("bench validate configs/procedures/demo.yaml",
                 [*bench, "validate", "configs/procedures/demo.yaml"]),
                ("bench schema stand", [*bench, "schema", "stand"])]
    return out


def child_env(pycache: str | None) -> dict[str, str]:
    """The children's environment: bytecode kept under `pycache` (None: as it is)."""
    env = {**os.environ, "COLUMNS": "100"}
    if pycache is not None:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = pycache
    return env


def time_once(argv: list[str], env: dict[str, str]) -> tuple[float, float]:
    """Wall and CPU seconds of one run of argv (its output discarded)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run(argv, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                       env=env, check=False)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(argv)}: exit {r.returncode}\n{r.stderr.decode()}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="timed runs of each case (5)")
    ap.add_argument("--parse-only", action="store_true",
                    help="only the cases that parse and print help or the version")
    ap.add_argument("--no-bytecode-cache", action="store_true",
                    help="run the children in this environment as it is (see above)")
    ap.add_argument("--imports", type=int, default=0, metavar="N",
                    help="list each case's N heaviest imports (cumulative microseconds)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bench-pycache-") as tmp:
        env = child_env(None if args.no_bytecode_cache else tmp)
        load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
        cached = ("as they are" if args.no_bytecode_cache
                  else "from compiled bytecode (a temporary PYTHONPYCACHEPREFIX)")
        print(f"load average {load} on {os.cpu_count()} CPUs; the modules {cached}; "
              f"PYTHONDONTWRITEBYTECODE {'set' if os.environ.get('PYTHONDONTWRITEBYTECODE') else 'unset'}"
              " here")
        print(f"{'case':<46} {'wall min':>9} {'median':>8} {'cpu min':>8} {'median':>8}  "
              f"goal (median wall <= {GOAL_S} s)")
        for name, cmd in cases(args.parse_only):
            report(name, cmd, env, args.repeat)
            if args.imports and not name.startswith("python"):
                for us, module in heaviest_imports(cmd, env, args.imports):
                    print(f"    {us / 1e6:8.3f} s  {module}")
    return 0


def heaviest_imports(argv: list[str], env: dict[str, str], n: int) -> list[tuple[int, str]]:
    """The n imports of one run of argv with the largest cumulative time (top-level
    modules and their children alike: a package's time includes what it imports)."""
    r = subprocess.run(argv, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                       env={**env, "PYTHONPROFILEIMPORTTIME": "1"}, check=False, text=True)
    rows = []
    for line in r.stderr.splitlines():
        if line.startswith("import time:") and "|" in line:
            _, cumulative, module = line.split("|")
            if cumulative.strip().isdigit():
                rows.append((int(cumulative), module.strip()))
    return sorted(rows, reverse=True)[:n]


def report(name: str, cmd: list[str], env: dict[str, str], repeat: int) -> None:
    """One case's line: wall and CPU seconds, min and median, and the goal."""
    time_once(cmd, env)                                 # warm the file cache (and compile)
    runs = [time_once(cmd, env) for _ in range(repeat)]
    walls, cpus = [w for w, _ in runs], [c for _, c in runs]
    wall_med = statistics.median(walls)
    goal = "" if name.startswith("python") else ("met" if wall_med <= GOAL_S else "MISSED")
    print(f"{name:<46} {min(walls):>9.3f} {wall_med:>8.3f} {min(cpus):>8.3f} "
          f"{statistics.median(cpus):>8.3f}  {goal}", flush=True)


if __name__ == "__main__":
    raise SystemExit(main())
