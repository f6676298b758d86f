"""Issue 22's stand, cut and resumed, on a machine with busy processes (on demand).

One axis, 6 turns at 2, 20 and 90 deg/s, a 1/rev and a 2/rev harmonic; SIGINT in the
90 deg/s pair's second half, then `bench run --resume`; every figure against the run's
own twin truth as tests/test_resume_truth.py counts them. Exit 0 when within the
binomial bound and none beyond 2.5 U.

    nice -n 10 python benchmarks/resume_two_per_rev.py               # paced (40), 2 busy
    nice -n 10 python benchmarks/resume_two_per_rev.py --clock max   # co-simulation
    ... --busy 0 | --busy-nice 0 (harsher: busy above a niced run) | --rates 20,90
    ... --keep DIR (keep the run) | --score RUN_DIR (score a finished run only)

History. On 2026-11-24 it FAILED on CI with 'outer +2 harmonic 1 amplitude (27.00 U)',
'outer +20 rate error (6.74 U)', 'outer +20 harmonic 1 amplitude (80.25 U)', figures
measured before the cut. Cause (2026-11-25): the check, not the bench. It scored the run
with tests/test_run_e2e.comparisons, which took the truth from the shipped stand file
(1/rev 8.6e-4, 2/rev 1.5e-4) instead of this stand's (5e-4, 3e-4); the harmonics also
set the mean turn rate's truth (~ sum a^2 / 2), hence the rate-error misses. The same
misses came on the co-simulation clock with no load at all (26.1 U, 5.7 U, 81.2 U).
Scored against the run's own stand.yaml, 96 figures each (worst |value - truth| / U):
co-sim quiet and co-sim beside 2 busy processes: identical result.json figures, 3
outside U (rate error 1.03, sigma 1.18, a 10 deg raw std inside its 99.9 % chi-square
interval); paced quiet: 6 outside, worst 1.16 U (harmonic 2 amplitude at 2 deg/s);
paced beside 2 busy processes: 7 outside, worst 1.81 U (rate error at +90 deg/s), a
second try 4 outside, worst 1.16 U (w0 at 90 deg/s); all within the binomial bound (13),
none beyond 2.5 U. Harsher, `--busy-nice 0 --rates 20,90` (busy processes above the niced
run, the paced clock slowed to ~22x): 64 figures, 2 outside, worst 1.23 U; no FOG frame
lost (the twin's pty applies back-pressure; the samples' time is their index, the
counter's start is tied by the FOG's sync pulse, neither moves with load). The one way
lateness can move the time axis, frames lost in whole counter wraps on a real link, is
refused by the rate ladder (procedures/rate_ladder/kind.py `_check_fog_indices`). See tests/test_resume_truth.py
(the co-sim case as a test).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from tests.test_resume_truth import (  # noqa: E402
    HARD_LIMIT_U,
    _interrupted_then_resumed,
    _truths,
    in_90dps_second_half,
    statements,
    two_per_rev,
)
from tests.test_run_e2e import allowed_outside, comparisons  # noqa: E402


def _busy(n: int, nice: int | None) -> list[subprocess.Popen[bytes]]:
    """`n` processes spinning on a CPU each: the load an operator's other programs put
    beside a run. `nice`: their priority (None: the benchmark's own, so that
    `nice -n 10 python benchmarks/...` loads the machine as two equal programs would;
    0 under a niced benchmark is a harsher load, where the co-simulation only slows)."""
    def prio() -> None:
        if nice is not None:
            os.setpriority(os.PRIO_PROCESS, 0, nice)
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"], preexec_fn=prio)
            for _ in range(n)]


def check(tmp_path: Path, clock_speed: float | str = 40, busy_n: int = 2,
          busy_nice: int | None = None, rates_dps: tuple[float, ...] = (2, 20, 90)
          ) -> list[str]:
    """Cut in the 90 deg/s pair's second half and resumed, with `busy_n` processes spinning
    beside it: every figure against the truth, the harmonic phases included."""
    busy = _busy(busy_n, busy_nice)
    try:
        run_dir = _interrupted_then_resumed(
            two_per_rev(tmp_path, clock_speed, rates_dps), tmp_path / "runs",
            in_90dps_second_half, cut_within_s=1800)
    finally:
        for b in busy:
            b.kill()
        for b in busy:
            b.wait()
    return score(run_dir)


def score(run_dir: Path) -> list[str]:
    """Every figure of a finished two-session run against its stand's truth: the
    misses beyond the hard limit, or the ones outside U when more than the binomial
    bound allows (empty: the run passes)."""
    result = json.loads((run_dir / "result.json").read_text())
    assert result["sessions"] == 2
    rows = [(what, abs(v - truth) / u) for what, v, u, truth
            in comparisons(result, _truths(run_dir))]
    phases = [w for w, _ in rows if "phase" in w and "90" in w]
    assert phases, [w for w, _ in rows]            # the 90 deg/s phases are compared
    rows += statements(result, _truths(run_dir), 1000.0)
    beyond = [f"{w} ({r:.2f} U)" for w, r in rows if r > HARD_LIMIT_U]
    outside = [f"{w} ({r:.2f} U)" for w, r in rows if r > 1.0]
    print(f"{len(rows)} figures, {len(outside)} outside U (allowed "
          f"{allowed_outside(len(rows))}), {len(beyond)} beyond {HARD_LIMIT_U} U")
    for line in outside:
        print("  outside:", line)
    for kind, (worst, what) in sorted(_worst_by_type(rows).items()):
        print(f"  worst {kind}: {worst:.2f} U ({what})")
    return beyond if beyond else ([] if len(outside) <= allowed_outside(len(rows))
                                  else outside)



def _worst_by_type(rows: list[tuple[str, float]]) -> dict[str, tuple[float, str]]:
    """Per figure type (the label less its axis and rate), the worst |value - truth| / U."""
    out: dict[str, tuple[float, str]] = {}
    for what, r in rows:
        kind = " ".join(what.split()[2:])
        if r >= out.get(kind, (-1.0, ""))[0]:
            out[kind] = (r, what)
    return out


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clock", default="40", help="sim clock_speed: a number or 'max'")
    ap.add_argument("--busy", type=int, default=2, help="busy processes beside the run")
    ap.add_argument("--busy-nice", type=int, default=None,
                    help="the busy processes' nice value (default: the benchmark's)")
    ap.add_argument("--rates", default="2,20,90",
                    help="the ladder's rates, deg/s (the issue's: 2,20,90; 20,90 is shorter)")
    ap.add_argument("--keep", help="keep the run in this folder")
    ap.add_argument("--score", help="only score this finished run directory")
    args = ap.parse_args()
    if args.score:
        bad = score(Path(args.score))
        print("FAIL" if bad else "PASS", *bad, sep="\n  ")
        sys.exit(1 if bad else 0)
    speed: float | str = args.clock if args.clock == "max" else float(args.clock)
    with tempfile.TemporaryDirectory() as d:
        where = Path(args.keep) if args.keep else Path(d)
        where.mkdir(parents=True, exist_ok=True)
        bad = check(where, speed, args.busy, args.busy_nice,
                    tuple(float(r) for r in args.rates.split(",")))
    print("FAIL" if bad else "PASS", *bad, sep="\n  ")
    sys.exit(1 if bad else 0)
