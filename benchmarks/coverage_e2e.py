"""Coverage of U (k = 2) through the whole bench, over stand seeds (run on demand).

    python benchmarks/coverage_e2e.py [--seeds 100:124] [--jobs 2] [--out DIR]

Runs the demo attestation (`bench run`, twins on real channels) once per stand seed, with
the shipped stand file copied and only its `sim.seed` changed, and pools the standardised
errors z = (value - truth) / u of every figure the stand's truth fixes (the same figures
the e2e test checks). A correct k = 2 U covers about 95 % and gives rms(z) near 1 in
every class of figure. The e2e test's count of figures outside U (tests/test_run_e2e.py)
rests on this: one run with one seed cannot tell a chance realisation from a U too small.
Seen 2026-11-22, 24 seeds: 96.0 % covered, rms 0.92, 0-5 of 62 outside per run.
"""

from __future__ import annotations

import argparse
import collections
import json
import math
import re
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tests.test_run_e2e import comparisons  # noqa: E402

STAND = ROOT / "configs" / "stands" / "sim-two-axis.yaml"
DEMO = ROOT / "configs" / "procedures" / "demo.yaml"


def run_seed(seed: int, out: Path) -> dict | None:
    (out / "stands").mkdir(parents=True, exist_ok=True)
    (out / "procedures").mkdir(exist_ok=True)
    stand_text, n = re.subn(r"(?m)^(\s+seed:\s*)\d+", rf"\g<1>{seed}", STAND.read_text())
    if n != 1:
        raise SystemExit(f"{STAND}: expected one 'seed:' line under sim:, found {n}")
    (out / "stands" / f"s{seed}.yaml").write_text(stand_text)
    proc = out / "procedures" / f"p{seed}.yaml"
    proc.write_text(DEMO.read_text().replace("../stands/sim-two-axis.yaml",
                                             f"../stands/s{seed}.yaml"))
    p = subprocess.run([sys.executable, "-m", "bench", "run", str(proc), "--yes", "--out",
                        str(out / "runs" / str(seed))], cwd=ROOT, capture_output=True,
                       text=True, timeout=600)
    if p.returncode != 0:
        print(f"seed {seed}: exit {p.returncode}: {p.stderr.strip()[-300:]}", flush=True)
        return None
    run_dir = Path(p.stdout.strip().splitlines()[-1])
    if not run_dir.is_absolute():
        run_dir = ROOT / run_dir
    return json.loads((run_dir / "result.json").read_text())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="100:124", help="first:end (end excluded)")
    ap.add_argument("--jobs", type=int, default=2, help="demo runs at once")
    ap.add_argument("--out", type=Path, default=None, help="keep the runs here")
    a = ap.parse_args()
    first, end = (int(x) for x in a.seeds.split(":"))
    out = a.out or Path(tempfile.mkdtemp(prefix="coverage-"))
    z: dict[str, list[float]] = collections.defaultdict(list)
    outside_per_run = []
    with ThreadPoolExecutor(a.jobs) as pool:
        for seed, result in zip(range(first, end),
                                pool.map(lambda s: run_seed(s, out), range(first, end)),
                                strict=True):
            if result is None:
                continue
            n_out = 0
            for what, value, u, truth in comparisons(result):
                axis, rest = what.split(" ", 1)
                kind = re.sub(r"^[+\-/\d.]+ ", "", rest)           # drop the rate
                zz = (value - truth) / (u / 2.0)
                z[f"{axis} {kind}"].append(zz)
                n_out += abs(zz) > 2.0
            outside_per_run.append(n_out)
            print(f"seed {seed}: {n_out} of {len(comparisons(result))} outside U", flush=True)
    every = [v for vs in z.values() for v in vs]
    if not every:
        print("no run completed")
        return 1
    print(f"\n{len(outside_per_run)} runs, {len(every)} figures: "
          f"covered {sum(abs(v) <= 2 for v in every) / len(every):.1%}, "
          f"rms z {math.sqrt(sum(v * v for v in every) / len(every)):.2f}; "
          f"outside per run {outside_per_run}")
    print(f"{'figure':32s}{'n':>5}{'covered':>9}{'rms z':>7}{'mean z':>8}")
    for kind, vs in sorted(z.items()):
        print(f"{kind:32s}{len(vs):5d}{sum(abs(v) <= 2 for v in vs) / len(vs):9.0%}"
              f"{math.sqrt(sum(v * v for v in vs) / len(vs)):7.2f}{sum(vs) / len(vs):+8.2f}")
    print(f"runs kept in {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
