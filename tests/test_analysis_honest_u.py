"""Every figure true within its U (issue 22): the rules that keep a U honest near zero.

Truths: hand-derived values (the chi-square quantile in closed form, the timing floor of
a known jitter), the stand model's own truth (sims.stand via tests/test_analysis_sim), and
Monte-Carlo draws with known variances. Statistical checks are counts with a stated
false-alarm rate (binomial tail at 1e-3), never "every one inside".
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.stats import binom, chi2

from bench.analysis.random_part import VarianceDifference, std_interval_u_rel
from bench.analysis.systematic import detection_threshold
from bench.analysis.turns import CounterBudget, analyze_turns
from bench.app.cli import main
from bench.report.conformity import judge_limit
from procedures.rate_ladder.analysis import sigma_check, with_sigma_terms
from procedures.rate_ladder.result import turns_entry
from tests.conftest import CONFIGS

FALSE_ALARM = 1e-3


def most_misses(n: int, p: float = 0.05) -> int:
    """Misses a correct 95 % statement exceeds with odds <= FALSE_ALARM."""
    return int(binom.isf(FALSE_ALARM, n, p))


# -- Type A of the rate error rests on at least the timing floor -------------------------

def test_type_a_never_rests_on_a_sigma_below_the_timing_floor() -> None:
    """4 turns at 360 deg/s (T = 1 s) with 1 us of edge jitter: floor sqrt(2) ppm per turn.
    Edges built with 0.01 ppm of scatter: the sample sigma is far below the floor, so the
    Type A term is the floor's, floor / sqrt(4), with 3 dof (k from them, method D1)."""
    budget = CounterBudget(trigger_jitter_s=1e-6)
    edges = 10.0 + np.arange(5) * 1.0 + np.array([0, 1e-8, -1e-8, 1e-8, 0])
    tr = analyze_turns([edges], 360.0, budget)
    floor = math.sqrt(2) * 1e-6
    assert tr.rate_instability_floor_rel == pytest.approx(floor)
    assert tr.rate_instability_rel < floor / 10
    assert tr.repeatability_u_rel == pytest.approx(floor / 2, rel=1e-9)
    assert tr.repeatability_dof == 3
    budget_t = turns_entry(tr).rate_error_budget
    assert budget_t is not None and "timing floor" in (budget_t.repeatability_basis or "")
    # a sample sigma above the floor is used as it is
    loud = 10.0 + np.arange(5) * 1.0 + np.array([0, 2e-5, -2e-5, 2e-5, 0])
    tl = analyze_turns([loud], 360.0, budget)
    assert tl.repeatability_u_rel == pytest.approx(tl.rate_instability_rel / 2, rel=1e-9)
    budget_l = turns_entry(tl).rate_error_budget
    assert budget_l is not None and (budget_l.repeatability_basis or "").startswith("sample")


def test_u_of_a_std_from_few_values_is_the_chi_square_interval() -> None:
    # hand-derived: 4 values (3 dof), chi2_0.025(3) = 0.2158: upper 3.728 s
    assert std_interval_u_rel(1.0, 4) == pytest.approx(math.sqrt(3 / chi2.ppf(0.025, 3)) - 1, rel=1e-9)
    assert std_interval_u_rel(1.0, 4) == pytest.approx(2.728, abs=1e-3)
    # many values: the normal approximation 2 s / sqrt(2 nu)
    assert std_interval_u_rel(1.0, 200_001) == pytest.approx(2 / math.sqrt(400_000), rel=1e-9)
    # a coverage count: s from 5 normal values, the truth 1 inside s +/- U
    rng = np.random.default_rng(7)
    s = np.std(rng.standard_normal((2000, 5)), axis=1, ddof=1)
    miss = sum(abs(x - 1.0) > std_interval_u_rel(float(x), 5) for x in s)
    assert miss <= most_misses(2000), miss


# -- one rule for "< L" ------------------------------------------------------------------

def test_an_unresolved_sigma_within_tolerance_passes_under_either_rule() -> None:
    """The demo's inner -100 deg/s: sigma 0.0032 ppm below a floor of 0.011 ppm, 4 turns;
    its 97.5 % limit is far inside the 10 ppm tolerance: PASS, stated as '< L'."""
    budget = CounterBudget(trigger_jitter_s=1e-6)
    edges = 10.0 + np.arange(5) * 1.0 + np.array([0, 1e-8, -1e-8, 1e-8, 0])
    entry = with_sigma_terms(turns_entry(analyze_turns([edges], 360.0, budget)))
    assert entry.rate_instability_resolved is False
    upper = entry.rate_instability_upper_rel
    assert upper is not None
    for rule in ("simple", "guard-band"):
        c = sigma_check("inner", 360.0, entry, 1e-5, rule)
        assert c.verdict == "pass" and c.one_sided is True, c
        assert c.upper_rel == upper < 1e-5
        # the same limit beyond the tolerance: not assessed (neither shown nor refuted)
        c = sigma_check("inner", 360.0, entry, upper / 2, rule)
        assert c.verdict == "not-assessed", c


def test_judge_limit_is_the_one_rule() -> None:
    assert judge_limit("x", 1.0, "q", 0.0, 1e-7, 9e-6, 1e-5, "simple", "95 %").verdict == "pass"
    assert judge_limit("x", 1.0, "q", 0.0, 1e-7, 1e-5, 1e-5, "guard-band",
                       "95 %").verdict == "pass"          # L = T is within it
    assert judge_limit("x", 1.0, "q", 0.0, 1e-7, 2e-5, 1e-5, "simple",
                       "95 %").verdict == "not-assessed"


# -- a difference of variances near zero -------------------------------------------------

@pytest.mark.parametrize("ratio", [0.0, 0.05, 0.3])
def test_floor_corrected_interval_covers_near_zero(ratio: float) -> None:
    """raw^2 = floor^2 + table^2, table = ratio * floor; raw from 3000 dof, the floor from
    2000: the statement (interval when resolved, '< L' otherwise) covers the table's
    sigma at 95 % or more; 'resolved' on a zero truth is rare (2.5 % by construction)."""
    rng = np.random.default_rng(11)
    floor, n_raw, n_floor, trials = 1.0, 3000, 2000, 300
    table = ratio * floor
    raw_true = math.hypot(floor, table)
    miss = resolved = 0
    for _ in range(trials):
        raw = raw_true * math.sqrt(rng.chisquare(n_raw) / n_raw)
        fl = floor * math.sqrt(rng.chisquare(n_floor) / n_floor)
        d = VarianceDifference.of(raw, n_raw, fl, n_floor)
        resolved += d.resolved
        ok = (d.lower <= table <= d.upper) if d.resolved else table <= d.upper
        miss += not ok
        assert d.upper > 0                         # never a limit of zero
    assert miss <= most_misses(trials), miss
    if ratio == 0.0:
        assert resolved <= most_misses(trials, 0.025), resolved


# -- detection with a stated false-alarm rate --------------------------------------------

def test_detection_threshold_is_sidak_over_the_tones_tested() -> None:
    for m in (1, 4, 7):
        alpha_1 = 1 - 0.95 ** (1 / m)
        assert detection_threshold(m) == pytest.approx(chi2.isf(alpha_1, 2), rel=1e-9)
    # pure noise: the chance that any of 4 tones passes is 5 %
    rng = np.random.default_rng(3)
    q = np.sum(rng.standard_normal((20_000, 4, 2)) ** 2, axis=2)
    rate = float(np.mean(np.any(q > detection_threshold(4), axis=1)))
    assert abs(rate - 0.05) < 0.006


# -- mains: stated, or found, never a silent 50 ------------------------------------------

@pytest.fixture
def demo60(tmp_path: Path) -> tuple[Path, Path]:
    """The demo with a 60 Hz grid in the twin's truth and no mains_hz anywhere."""
    (tmp_path / "stands").mkdir()
    (tmp_path / "procedures").mkdir()
    stand = tmp_path / "stands" / "sim-two-axis.yaml"
    proc = tmp_path / "procedures" / "demo.yaml"
    s = yaml.safe_load((CONFIGS / "stands" / "sim-two-axis.yaml").read_text())
    for ax in s["sim"]["axes"].values():
        ax["mains"]["frequency_hz"] = 60
    stand.write_text(yaml.safe_dump(s))
    shutil.copy(CONFIGS / "procedures" / "demo.yaml", proc)
    text = proc.read_text()
    proc.write_text("\n".join(x for x in text.splitlines() if not x.startswith("mains_hz")))
    return proc, stand


def test_validate_names_the_mains_key_when_none_is_set(
        demo60: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    proc, stand = demo60
    assert main(["validate", str(proc)]) == 0
    out = capsys.readouterr().out
    assert "mains_hz not set" in out and "found from the data" in out
    # a stated grid that the twin's truth contradicts is refused at the key
    s = yaml.safe_load(stand.read_text())
    s["mains_hz"] = 50
    stand.write_text(yaml.safe_dump(s))
    assert main(["validate", str(proc)]) == 2
    assert "mains_hz" in capsys.readouterr().err
    s["mains_hz"] = 60
    stand.write_text(yaml.safe_dump(s))
    assert main(["validate", str(proc)]) == 0
    assert "mains_hz not set" not in capsys.readouterr().out


def test_type_a_is_pooled_over_the_pair_s_two_directions() -> None:
    """+ turns that happen to agree to 0.01 ppm, - turns that scatter by ~20 ppm: each
    direction's Type A rests on the pooled sigma (6 dof), not on its own 3-dof sample."""
    from bench.analysis.turns import pool_type_a

    budget = CounterBudget(trigger_jitter_s=1e-9)
    quiet = 10.0 + np.arange(5) * 1.0 + np.array([0, 1e-8, -1e-8, 1e-8, 0])
    loud = 10.0 + np.arange(5) * 1.0 + np.array([0, 2e-5, -2e-5, 2e-5, 0])
    plus, minus = pool_type_a([analyze_turns([quiet], 360.0, budget),
                               analyze_turns([loud], -360.0, budget)])
    rel = [np.asarray(r.counter_rate_dps) / 360.0 for r in (plus, minus)]
    pooled = math.sqrt(sum(float(np.sum((x - x.mean()) ** 2)) for x in rel) / 6)
    for r in (plus, minus):
        assert r.repeatability_u_rel == pytest.approx(pooled / 2, rel=1e-9)
        assert "pooled" in r.repeatability_basis and "6 dof" in r.repeatability_basis
        assert r.repeatability_dof == 6
        # the Type A term dominates: nu_eff ~ 6, k = t_95.45(6) = 2.52 (EA-4/02 table E.1)
        assert r.coverage_factor == 2.52
        assert r.rate_error_u_rel == pytest.approx(2.52 * math.sqrt(
            r.timing_u_rel ** 2 + r.timebase_u_rel ** 2 + r.repeatability_u_rel ** 2))
