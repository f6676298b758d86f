"""Result records: one per commanded rate and direction, one per +/- pair (CONTRACT §3).

API
    RateResult.to_dict()  -> the `axes.<axis>.rates[]` entry (binding keys plus extras)
    PairResult.to_dict()  -> the `axes.<axis>.pairs[]` entry
    PairAnalysis(rates=(plus, minus), pair)
    judge_rate(result, tolerance_rel, capability_max=0.3) -> RateResult with a verdict

Binding keys are produced exactly as CONTRACT §3 names them; extras sit beside them.
Relative values are plain fractions. Non-finite numbers become None (JSON null) so that a
result.json never carries NaN.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from bench.analysis.crosscal import CrossCalibration
from bench.analysis.random_part import RandomPartResult, std_interval_u_rel
from bench.analysis.systematic import (
    BinnedSystematic,
    HarmonicResult,
    MainsResult,
    NoiseInflation,
)
from bench.analysis.turns import TurnsResult

# RMG 63-2003: the measurement's error limit within 0.2-0.3 of the tolerance (docs/method.md A6)
CAPABILITY_MAX = 0.3


def clean(x: object) -> Any:
    """Replace non-finite floats by None, recursively (JSON has no NaN)."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: clean(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [clean(v) for v in x]
    return x


@dataclass(frozen=True)
class SystematicResult:
    harmonics: tuple[HarmonicResult, ...]
    mains: MainsResult | None
    binned: BinnedSystematic
    residual_std_dps: float             # of the fit, deg/s of table rate
    inflation: NoiseInflation           # applied to the harmonic and mains uncertainties
    detection: Mapping[str, str | float] = dataclasses.field(default_factory=dict)  # the rule

    def to_dict(self) -> dict[str, object]:
        return {"harmonics": [h.to_dict() for h in self.harmonics],
                "mains": self.mains.to_dict() if self.mains else None,
                "binned": self.binned.to_dict(),
                "residual_std_dps": self.residual_std_dps,
                "noise_inflation": self.inflation.to_dict(),
                "detection": dict(self.detection)}


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

    def to_dict(self) -> dict[str, Any]:
        tr = self.turns_result
        d: dict[str, Any] = tr.to_dict()
        d["intra_turn_instability_rel"] = self.random.instability_rel
        d["intra_turn_instability_corrected_rel"] = self.random.corrected_rel
        # docs/method.md A5: U of a std from the record's samples (white random part assumed)
        d["intra_turn_instability_u_rel"] = std_interval_u_rel(self.random.instability_rel,
                                                      self.random.samples)
        # docs/method.md A5: the corrected figure's U only when it is resolved (JCGM 101);
        # otherwise it is stated as '< intra_turn.corrected_upper_rel'
        d["intra_turn_instability_corrected_u_rel"] = self.random.corrected_u_rel
        d["systematic"] = self.systematic.to_dict()
        d["intra_turn"] = self.random.to_dict()
        d["windows"] = [dict(w) for w in self.windows]
        if self.verdict is not None:
            d["verdict"] = self.verdict
            d["judgement"] = self.judgement
        out: dict[str, Any] = clean(d)
        return out


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

    def to_dict(self) -> dict[str, Any]:
        d = {"rate_dps": self.rate_dps, **self.cal.to_dict(),
             "noise_inflation": self.noise_inflation.to_dict(),
             "half_sessions": list(self.sessions), "bias_model": self.bias_model}
        out: dict[str, Any] = clean(d)
        return out


@dataclass(frozen=True)
class PairAnalysis:
    rates: tuple[RateResult, ...]       # the '+' direction, then the '-' direction
    pair: PairResult

    def to_dict(self) -> dict[str, Any]:
        return {"rates": [r.to_dict() for r in self.rates], "pair": self.pair.to_dict()}


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
