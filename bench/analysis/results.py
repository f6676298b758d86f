"""Result records: one per commanded rate and direction, one per +/- pair (docs/method.md
A1-A5), as typed values.

API
    RateResult, PairResult, SystematicResult, PairAnalysis(rates=(plus, minus), pair)
    judge_rate(result, tolerance_rel, capability_max=0.3) -> RateResult with a verdict

They spell no result.json key: the rate ladder's result module
(procedures/rate_ladder/result.py `rate_entry`, `pair_entry`) lays them out as CONTRACT §3's
`axes.<axis>.rates[]` and `pairs[]`, and reads them back, in one place.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

from bench.analysis.crosscal import CrossCalibration
from bench.analysis.random_part import RandomPartResult
from bench.analysis.systematic import (
    BinnedSystematic,
    HarmonicResult,
    MainsResult,
    NoiseInflation,
)
from bench.analysis.turns import TurnsResult

# RMG 63-2003: the measurement's error limit within 0.2-0.3 of the tolerance (docs/method.md A6)
CAPABILITY_MAX = 0.3


@dataclass(frozen=True)
class SystematicResult:
    harmonics: tuple[HarmonicResult, ...]
    mains: MainsResult | None
    binned: BinnedSystematic
    residual_std_dps: float             # of the fit, deg/s of table rate
    inflation: NoiseInflation           # applied to the harmonic and mains uncertainties
    detection: Mapping[str, str | float] = dataclasses.field(default_factory=dict)  # the rule


@dataclass(frozen=True)
class RateResult:
    """docs/method.md A1-A5 for one commanded rate and direction."""

    turns_result: TurnsResult
    systematic: SystematicResult
    random: RandomPartResult
    windows: tuple[dict[str, float | int], ...]   # the timed windows of this direction
    verdict: str | None = None
    judgement: dict[str, object] | None = None

    @property
    def set_rate_dps(self) -> float:
        return self.turns_result.set_rate_dps

    @property
    def rate_error_rel(self) -> float:
        return self.turns_result.rate_error_rel

    @property
    def rate_error_u_rel(self) -> float:
        return self.turns_result.rate_error_u_rel


@dataclass(frozen=True)
class PairResult:
    """docs/method.md A3 for one +/- pair."""

    rate_dps: float
    cal: CrossCalibration
    noise_inflation: NoiseInflation     # applied to the FOG half-mean uncertainties
    # which session acquired each half (in order), and how the FOG bias is modelled
    sessions: tuple[int, ...] = ()
    bias_model: str = "one session: one bias and one linear drift for the pair"

    @property
    def k(self) -> float:
        return self.cal.k

    @property
    def k_u(self) -> float:
        return self.cal.k_u

    @property
    def w0_dps(self) -> float:
        return self.cal.w0_dps

    @property
    def w0_u_dps(self) -> float:
        return self.cal.w0_u_dps


@dataclass(frozen=True)
class PairAnalysis:
    rates: tuple[RateResult, ...]       # the '+' direction, then the '-' direction
    pair: PairResult


def judge_rate(result: RateResult, tolerance_rel: float,
               capability_max: float = CAPABILITY_MAX) -> RateResult:
    """Simple acceptance of the rate error against a tolerance, with the capability check.

    pass: |rate_error_rel| <= tolerance_rel. The judgement also states U / tolerance and
    whether it is within capability_max (RMG 63-2003: 0.2-0.3); when it is not, the
    measurement is not capable of the check, which the certificate must say.
    """
    if not tolerance_rel > 0:
        raise ValueError(f"tolerance_rel must be > 0, got {tolerance_rel}")
    err, u = result.rate_error_rel, result.rate_error_u_rel
    ratio = u / tolerance_rel
    judgement = {"tolerance_rel": tolerance_rel, "decision_rule": "simple acceptance",
                 "capability_ratio": ratio, "capability_max": capability_max,
                 "capable": ratio <= capability_max}
    verdict = "pass" if abs(err) <= tolerance_rel else "fail"
    return dataclasses.replace(result, verdict=verdict, judgement=judgement)
