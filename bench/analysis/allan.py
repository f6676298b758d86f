"""Allan deviation of a FOG record, and the FOG's white-noise floor (docs/method.md A5).

API
    allan_deviation(rate_dps, rate_hz, m=None) -> AllanCurve   # overlapping estimator
    white_noise(rate_dps) -> (sigma, pairs)                    # ADEV at tau0, one pass

Why the Allan deviation at the sample interval tau0 = 1 / rate_hz: for a FOG whose noise
is white at its output rate it equals the per-sample standard deviation, while slow
terms (bias, Earth rate on a static record, drift) drop out of successive differences.
That is the floor the table's intra-turn instability is corrected for (in quadrature).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

_CHUNK = 1 << 20


@dataclass(frozen=True)
class AllanCurve:
    tau_s: tuple[float, ...]
    adev: tuple[float, ...]          # same unit as the record
    terms: tuple[int, ...]           # number of overlapping differences at each tau


def white_noise(rate: np.ndarray) -> tuple[float, int]:
    """sqrt(mean((y[i+1] - y[i])^2) / 2): ADEV at tau0; and the number of differences.

    Its variance estimate has a relative standard uncertainty of about sqrt(3 / pairs)
    for white noise (successive squared differences overlap one sample)."""
    y = np.asarray(rate, dtype=float)
    if y.ndim != 1 or y.size < 3:
        raise ValueError("white_noise: need a 1-D record of at least 3 samples")
    total = 0.0
    for c0 in range(0, y.size - 1, _CHUNK):
        d = np.diff(y[c0:min(c0 + _CHUNK + 1, y.size)])
        total += float(d @ d)
    pairs = y.size - 1
    return math.sqrt(total / pairs / 2.0), pairs


def allan_deviation(rate: np.ndarray, rate_hz: float, m: np.ndarray | None = None
                    ) -> AllanCurve:
    """Overlapping Allan deviation at tau = m / rate_hz (default: octaves up to n / 4)."""
    y = np.asarray(rate, dtype=float)
    n = y.size
    if y.ndim != 1 or n < 4:
        raise ValueError("allan_deviation: need a 1-D record of at least 4 samples")
    if m is None:
        m = 2 ** np.arange(int(math.log2(n // 4)) + 1)
    m = np.asarray(m, dtype=np.int64)
    if np.any(m < 1) or np.any(2 * m >= n):
        raise ValueError("allan_deviation: averaging factors must be 1 <= m < n / 2")
    # cumulative sum of the rate minus its mean (precision): one allocation of n + 1
    x = np.empty(n + 1)
    x[0] = 0.0
    np.subtract(y, y.mean(), out=x[1:])
    np.cumsum(x[1:], out=x[1:])
    out, terms = [], []
    for mm in m:
        d = x[2 * mm:] - 2.0 * x[mm:-mm] + x[:-2 * mm]
        out.append(math.sqrt(float(d @ d) / (2.0 * mm * mm * d.size)))
        terms.append(int(d.size))
    return AllanCurve(tau_s=tuple((m / rate_hz).tolist()), adev=tuple(out),
                      terms=tuple(terms))
