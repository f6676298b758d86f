"""A short coverage campaign over every stratum (the long one: benchmarks/coverage_analysis.py).

Each figure type, per stratum, must not miss its truth more often than a correct 95 %
statement would with odds of 1e-3 (binomial tail), and false 'detected' / 'resolved'
claims must stay within what 5 % allows. Few seeds, so only gross failures show (a
resumed half on the wrong FOG bias put half the intra-turn figures outside); the long
campaign measures the coverage itself.
"""

from __future__ import annotations

import collections

import pytest
from scipy.stats import binom

from benchmarks.coverage_analysis import figures, strata

SEEDS = range(900, 903)
FALSE_ALARM = 1e-3


@pytest.mark.timeout(600)
@pytest.mark.parametrize("name", sorted(strata()))
def test_short_campaign_covers_the_truth(name: str) -> None:
    st = strata()[name]
    cells: dict[str, list[int]] = collections.defaultdict(lambda: [0, 0])
    for seed in SEEDS:
        for what, ok in figures(name, st, seed, 50.0, 4):
            c = cells[what]
            c[0] += int(bool(ok))
            c[1] += 1
    assert cells["rate error"][1] == 2 * len(SEEDS)
    bad = []
    for what, (ok, n) in cells.items():
        if what.startswith("false"):
            claims = ok
            if claims > binom.isf(FALSE_ALARM, n, 0.05):
                bad.append(f"{what}: {claims} of {n}")
        elif n - ok > binom.isf(FALSE_ALARM, n, 0.05):
            bad.append(f"{what}: {n - ok} of {n} outside")
    assert not bad, bad
    if name == "mains60":
        assert cells["mains frequency"] == [2 * len(SEEDS), 2 * len(SEEDS)]
