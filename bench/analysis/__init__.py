"""docs/method.md part A as a library: no I/O, numbers in, frozen results out.

Entry point: `analyze_pair(halves, set_rate_dps, fog_rate_hz=..., ...) -> PairAnalysis`
(pair.py). Modules, each a step of docs/method.md A:

    turns.py        A1/A2  per-turn rates, rate error and U (k = 2), rate instability
    window.py              exact FOG integrals over each half's whole turns
    crosscal.py     A3     k, w0 (and drift) with U, eq. 5/6 or the drift-cancelling fit
    angle.py        A4     the table angle of each FOG sample from zero marks
    sums.py         A4/A5  the one chunked pass over the samples
    systematic.py   A4     harmonic + mains fit, binned estimator
    random_part.py  A5     random part, FOG noise floor, averaged instabilities
    allan.py        A5     Allan deviation, white-noise floor
    results.py             RateResult / PairResult -> result.json entries (CONTRACT §3)
"""

from bench.analysis.angle import FogCalibration, sample_angles_deg
from bench.analysis.blas import one_blas_thread
from bench.analysis.crosscal import CrossCalibration, HalfMean, cross_calibrate
from bench.analysis.pair import analyze_pair
from bench.analysis.results import PairAnalysis, PairResult, RateResult, judge_rate
from bench.analysis.turns import CounterBudget, analyze_turns, period_rate_error
from bench.analysis.window import HalfRecord, Window

# every product of the analysis on one BLAS thread, whatever the machine's cores (blas.py)
one_blas_thread()

__all__ = [
    "CounterBudget", "CrossCalibration", "FogCalibration", "HalfMean", "HalfRecord",
    "PairAnalysis", "PairResult", "RateResult", "Window", "analyze_pair", "analyze_turns",
    "cross_calibrate", "judge_rate", "period_rate_error", "sample_angles_deg",
]
