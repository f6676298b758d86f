"""Acceptance (issue 22): the demo interrupted in settle, mid-acquire and between axes, each
resumed: every figure of every rate against the twin's truth, phases included.

Real CLI in a subprocess, twins on real channels, SIGINT as an operator's Ctrl-C, then
`bench run --resume` (its console script's `main`, in the test process). The figures: those of tests/test_run_e2e.comparisons (k, w0, rate
error, harmonic amplitudes and phases, mains) and the ones it leaves out: eq. 2's sigma,
the intra-turn instability raw and floor-corrected, the stability over 1, 10 and 360 deg,
raw and corrected. A two-sided figure (value +/- U) is counted outside when it misses by
more than U (a correct 95 % U misses now and then: the count has a binomial false-alarm
rate of 1e-3 and a hard limit of 2.5 U); a one-sided statement ('< L') misses when the
truth is above L, counted the same way.
"""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml
from scipy.stats import chi2, norm

from sims.stand import AxisTruth
from tests.conftest import CONFIGS, ROOT, cli, wait_for_cut
from tests.test_run_e2e import allowed_outside, comparisons

STAND = CONFIGS / "stands" / "sim-two-axis.yaml"
DEMO = CONFIGS / "procedures" / "demo.yaml"
HARD_LIMIT_U = 2.5
#: the two-sided level of the hard limit: 2.5 U (k = 2) of a normal figure is 4.9 sigma
HARD_LEVEL = 1.0 - 2.0 * norm.sf(2.0 * HARD_LIMIT_U)


def _demo(tmp_path: Path) -> Path:
    """The demo on its own stand, the co-simulation clock (`clock_speed: max`).

    It ran on the paced clock at 40x until issue 27, so that a step lasted long enough
    to be cut. Beside two busy processes that clock slowed itself to the twins' pace, the
    FOG driver's real-time wrap check (drivers/fog.py `_watch_clock`, armed only when
    half a counter wrap lasts 20 ms of real time) armed, and the starved reader's jitter
    set it off: the resumed run aborted on 'indices uncertain'. That is real-time
    behaviour, tests/test_fog_driver.py's subject, not this test's. On the co-simulation
    the cut still lands in the phase's step or the one after (the demo's co-simulation
    runs about as fast as 40x), and every figure depends on the cut's moment alone."""
    proc = yaml.safe_load(DEMO.read_text())
    proc["stand"] = str(STAND)
    proc["static_record_s"] = 10
    (tmp_path / "demo.yaml").write_text(yaml.safe_dump(proc))
    return tmp_path / "demo.yaml"


def two_per_rev(tmp_path: Path, clock_speed: float | str = "max",
                rates_dps: tuple[float, ...] = (2, 20, 90)) -> Path:
    """Issue 22's stand: one axis, 6 turns at 2, 20 and 90 deg/s, a 1/rev and a 2/rev
    harmonic (at 90 deg/s an 85 ms offset between FOG and counter moved the 2/rev phase
    by 15 deg before the FOG's flush at connect was fixed, issue 27)."""
    stand = yaml.safe_load(STAND.read_text())
    del stand["axes"]["inner"], stand["sim"]["axes"]["inner"]
    stand["sim"]["clock_speed"] = clock_speed
    stand["sim"]["axes"]["outer"]["harmonics"] = [
        {"order": 1, "amplitude_rel": 5.0e-4, "phase_deg": 40},
        {"order": 2, "amplitude_rel": 3.0e-4, "phase_deg": -70}]
    (tmp_path / "stand.yaml").write_text(yaml.safe_dump(stand))
    proc = yaml.safe_load(DEMO.read_text())
    proc.update(stand=str(tmp_path / "stand.yaml"), turns=6, static_record_s=10,
                harmonics=2, axes={"outer": {"rates_dps": list(rates_dps)}})
    (tmp_path / "two-per-rev.yaml").write_text(yaml.safe_dump(proc))
    return tmp_path / "two-per-rev.yaml"


def in_90dps_second_half(ev: list[dict[str, Any]]) -> bool:
    """The cut of issue 22's 2/rev case: the 90 deg/s pair's second half has started."""
    return any(e["event"] == "step_start" and e.get("action") == "acquire"
               and e.get("unit") == "outer/90dps" and "half 2/" in e.get("describe", "")
               for e in ev)


def _events(run_dir: Path) -> list[dict[str, Any]]:
    out = []
    for line in (run_dir / "events.jsonl").read_text().splitlines():
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:     # a line being written
            break
    return out


PHASES: dict[str, Callable[[list[dict[str, Any]]], bool]] = {
    "settle": lambda ev: any(e["event"] == "step_start" and e.get("action") == "settle"
                             and e.get("unit") == "outer/50dps" for e in ev),
    "acquire": lambda ev: any(e["event"] == "step_start" and e.get("action") == "acquire"
                              and e.get("unit") == "outer/50dps"
                              and "half 2/" in e.get("describe", "") for e in ev),
    "between-axes": lambda ev: _second_axis_started(ev),
}


def _second_axis_started(ev: list[dict[str, Any]]) -> bool:
    """The first axis is done and the next one's first step (its prompt) has started."""
    axes = [e.get("axis") for e in ev if e["event"] == "step_start" and e.get("axis")]
    return bool(axes) and any(a != axes[0] for a in axes)


def _interrupted_then_resumed(proc: Path, out: Path,
                              when: Callable[[list[dict[str, Any]]], bool],
                              cut_within_s: float = 240) -> Path:
    """`bench run`, SIGINT once `when(events)` holds (the run must get there within
    `cut_within_s` of real time: on a loaded machine the co-simulation runs slower), then
    `bench run --resume` (the console script's `main` in this process: the Ctrl-C needed
    a process of its own, the resume does not, and it spares an interpreter's start-up and
    imports): the run directory."""
    p = subprocess.Popen([sys.executable, "-m", "bench", "run", str(proc), "--yes",
                          "--out", str(out)], cwd=ROOT, text=True,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        run_dir = wait_for_cut(p, out, when, cut_within_s)
        p.send_signal(signal.SIGINT)
        o, e = p.communicate(timeout=max(120, cut_within_s / 2))
    except BaseException:
        p.kill()                          # a failed test leaves no run behind
        o, e = p.communicate()
        raise
    assert p.returncode == 3, o + e
    r = cli("run", "--resume", str(run_dir), "--yes")
    assert r.returncode == 0, r.stdout + r.stderr
    return run_dir


def _truths(run_dir: Path) -> dict[str, AxisTruth]:
    sim = yaml.safe_load((run_dir / "stand.yaml").read_text())["sim"]
    return {a: AxisTruth.from_mapping(t) for a, t in sim["axes"].items()}


def statements(result: dict[str, Any], truths: dict[str, AxisTruth], fog_hz: float
               ) -> list[tuple[str, float]]:
    """(what, how far outside its statement in units of U: <= 1 covers; for '< L', 1.0 +
    (truth - L) / L when above) for the figures comparisons() leaves out."""
    out = []
    for axis, ax in result["axes"].items():
        t = truths[axis]
        fog = t.fog
        for r in ax["rates"]:
            where = f"{axis} {r['set_rate_dps']:+g}"
            w = abs(r["set_rate_dps"])
            period = 360.0 / w
            floor = r["rate_instability_floor_rel"]
            table_turn = t.rate_noise_dps / math.sqrt(period * fog_hz) / w
            s, su = r["rate_instability_rel"], r["rate_instability_u_rel"]
            if r["rate_instability_resolved"]:
                out.append((f"{where} sigma", abs(s - math.hypot(table_turn, floor)) / su))
            else:
                out.append((f"{where} sigma < L", _limit(table_turn,
                                                          r["rate_instability_upper_rel"])))
            it = r["intra_turn"]
            raw_t = math.hypot(fog.noise_dps / fog.k, t.rate_noise_dps) / w
            cor_t = t.rate_noise_dps / w
            out.append((f"{where} intra-turn raw", abs(it["instability_rel"] - raw_t)
                        / r["intra_turn_instability_u_rel"]))
            out.append((f"{where} intra-turn corrected",
                        _interval(cor_t, it["corrected_lower_rel"], it["corrected_upper_rel"],
                                  it["resolved"])))
            for a in it["averaged"]:
                n_b = a["samples_per_block"]
                label = f"{where} {a['angle_deg']:g} deg"
                truth = raw_t / math.sqrt(n_b)
                if a.get("dof"):  # a standard deviation: its own chi-square interval
                    out.append((f"{label} raw", _chi2_outside(a["instability_rel"], truth,
                                                              int(a["dof"]))))
                else:
                    out.append((f"{label} raw", abs(a["instability_rel"] - truth)
                                / a["u_rel"]))
                out.append((f"{label} corrected",
                            _interval(cor_t / math.sqrt(n_b), a["corrected_lower_rel"],
                                      a["corrected_upper_rel"], a["resolved"])))
    return out


def _chi2_outside(s: float, truth: float, dof: int) -> float:
    """A sample std against its true value by the chi-square interval of a std with `dof`
    degrees of freedom (docs/method.md A5): 0 inside the 95 % interval; 1.5 (counted
    outside, within the binomial bound) inside the hard interval; beyond the hard limit
    else. A symmetric +/- U misjudges a std with 2 degrees of freedom (the 360 deg
    figure of a few turns): its sampling distribution is far from normal, and 1 run in
    12 of the demo put one such figure past 2.5 U while inside its 99.9 % interval.

    The hard interval's level is the hard limit's own: 2.5 U of a normal figure (k = 2) is
    4.9 sigma, missed by a correct U once in a million. A 99.9 % interval here was not the
    same bar: the suite scores about a hundred such figures, so a correct U failed one
    suite in ten (CI, 25 Nov: 'outer +200 1 deg raw', a std of 1438 dof just outside its
    99.9 % interval, every other figure inside)."""
    def interval(level: float) -> tuple[float, float]:
        tail = (1 - level) / 2
        return (s * math.sqrt(dof / chi2.ppf(1 - tail, dof)),
                s * math.sqrt(dof / chi2.ppf(tail, dof)))
    lo, hi = interval(0.95)
    if lo <= truth <= hi:
        return 0.0
    lo, hi = interval(HARD_LEVEL)
    return 1.5 if lo <= truth <= hi else HARD_LIMIT_U + 1.0


def _limit(truth: float, limit: float) -> float:
    return 0.0 if truth <= limit else 1.0 + (truth - limit) / limit


def _interval(truth: float, lower: float, upper: float, resolved: bool) -> float:
    if not resolved:
        return _limit(truth, upper)
    if lower <= truth <= upper:
        return 0.0
    half = max(upper - lower, 1e-300) / 2
    return 1.0 + min(abs(truth - lower), abs(truth - upper)) / half


@pytest.mark.timeout(900)
@pytest.mark.parametrize("phase", sorted(PHASES))
def test_resumed_demo_recovers_every_truth(phase: str, tmp_path: Path) -> None:
    run_dir = _interrupted_then_resumed(_demo(tmp_path), tmp_path / "runs", PHASES[phase])
    result = json.loads((run_dir / "result.json").read_text())
    assert result["verdict"] == "pass" and result["sessions"] == 2
    sessions = {e["session"] for e in _events(run_dir) if e["event"] == "acquire"}
    assert sessions == {1, 2}, sessions                # both sessions measured
    rows = [(what, abs(v - truth) / u) for what, v, u, truth
            in comparisons(result, _truths(run_dir))]
    rows += statements(result, _truths(run_dir), 1000.0)
    beyond = [f"{w} ({r:.2f} U)" for w, r in rows if r > HARD_LIMIT_U]
    assert not beyond, beyond
    outside = [f"{w} ({r:.2f} U)" for w, r in rows if r > 1.0]
    assert len(outside) <= allowed_outside(len(rows)), (len(rows), outside)
    # the sigma checks: '< L' within the tolerance passes, by the one rule
    sig = [c for c in result["checks"] if c["quantity"] == "rate_instability"]
    assert sig and all(c["verdict"] == "pass" for c in sig), sig


@pytest.mark.timeout(900)
def test_resumed_two_per_rev_stand_recovers_every_truth(tmp_path: Path) -> None:
    """Issue 22's second acceptance item: its stand (one axis, 6 turns, 1/rev and 2/rev
    harmonics; here at 20 and 90 deg/s, the benchmark adds the issue's 2 deg/s, whose
    12-minute halves double this test's cost), cut in the 90 deg/s pair's second half and
    resumed: every figure, the 90 deg/s phases included, against the run's own truth.

    On the co-simulation clock (`clock_speed: max`), whose results do not depend on
    machine load: tests/test_determinism.py proves that by running the demo beside two
    busy processes and finding every figure the same, so this test spends no CPU on
    busy processes. benchmarks/resume_two_per_rev.py runs the case beside them (co-sim
    or the paced clock) on demand; seen on 2026-11-25: the same result.json figures
    quiet and beside two busy processes, 3 of 96 outside U, none beyond 1.5 U.
    """
    run_dir = _interrupted_then_resumed(two_per_rev(tmp_path, rates_dps=(20, 90)),
                                        tmp_path / "runs", in_90dps_second_half)
    result = json.loads((run_dir / "result.json").read_text())
    assert result["verdict"] == "pass" and result["sessions"] == 2
    truths = _truths(run_dir)
    rows = [(what, abs(v - truth) / u) for what, v, u, truth
            in comparisons(result, truths)]
    assert {"outer +90 harmonic 2 phase", "outer -90 harmonic 2 phase"} <= {w for w, _ in rows}
    rows += statements(result, truths, 1000.0)
    beyond = [f"{w} ({r:.2f} U)" for w, r in rows if r > HARD_LIMIT_U]
    assert not beyond, beyond
    outside = [f"{w} ({r:.2f} U)" for w, r in rows if r > 1.0]
    assert len(outside) <= allowed_outside(len(rows)), (len(rows), outside)


def test_a_record_on_uncertain_fog_indices_is_refused() -> None:
    """Frames lost in whole counter wraps (drivers/fog.py flags `index_uncertain_from`
    from the clock, as tests/test_fog_driver.py shows on a paced twin) put every later
    sample on the wrong time: the half is refused with the driver's cause, not analysed.

    The driver here is a real, unopened `Fog` with the flag set as its own clock watch
    sets it: the paced rig that makes the loss happens in real time, and the guide keeps
    new wall-clock dependent tests out of the suite."""
    from bench.core.engine import Abort
    from drivers.fog import Fog
    from procedures.rate_ladder.kind import _check_fog_indices
    from sims.clock import VirtualClock

    fog = Fog("/dev/null", fmt="kvh-a", axis="z", rate_hz=1000.0, units="deg/s",
              raw_path=None, clock=VirtualClock(1.0, running=False))
    _check_fog_indices(fog, 5000, "outer +90 deg/s half 2")          # nothing flagged
    fog._index_uncertain_from = 4000
    fog.last_error = "FOG on /dev/null: frames were lost in whole counter wraps (128)"
    _check_fog_indices(fog, 4000, "outer +90 deg/s half 1")          # ends before it
    with pytest.raises(Abort, match=r"half 2: the FOG's sample indices from 4000 on are "
                                    r"uncertain \(FOG on /dev/null: frames were lost"):
        _check_fog_indices(fog, 5000, "outer +90 deg/s half 2")
