"""When a turning axis has settled: transients count, a steady ripple of the turn does not.

A rate table's rate carries a once-per-turn ripple and its harmonics for as long as it
turns (bearing and motor geometry; the seed paper's outer axis: 8.6e-4 of the rate, once
per turn). Judged sample by sample, a ripple larger than the tolerance never "settles"
however long the table turns: at -50 deg/s with tolerance 1e-3 of the rate the ripple
touches 0.0502 deg/s once a turn, every 7.2 s, and a 20 s hold never completes.

So where the hold spans at least `MIN_TURNS` whole turns, the periodic part of the rate
(docs/method.md A4: w(phi) = w0 + sum_h a_h cos(h phi) + b_h sin(h phi), the table's
angle phi from the drive's position) is fitted by least squares over the hold and set
aside, and what is left (the mean and anything not periodic in the turn: a velocity
step, a slow drift, noise) is held to the tolerance. Two turns at least, because over
a single turn a Fourier series of a few orders can absorb part of a step; over two, a
transient in one turn and not in the other is not periodic. A hold shorter than two
turns (slow rates) is judged sample by sample, as before. The ripple set aside is
returned, so the run states it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

#: whole turns a hold must span before the turn's periodic ripple is set aside
MIN_TURNS = 2.0
#: harmonics of the turn fitted (once per turn and its first multiples)
MAX_ORDER = 4


@dataclass(frozen=True)
class RippleJudgement:
    """The hold judged with the turn's periodic ripple set aside."""

    settled: bool
    mean_dps: float               # the fitted constant: the mean rate over whole turns
    ripple_peak_dps: float        # largest |periodic part| over the hold
    worst_residual_dps: float     # largest |rate - ripple - target|
    turns: float                  # turns the hold spans
    orders: int                   # harmonics fitted
    last_out: int | None          # index of the last reading out of tolerance (None: none)


def judge_with_ripple(t_s: Sequence[float], velocity_dps: Sequence[float],
                      position_deg: Sequence[float], target_dps: float,
                      tolerance_dps: float, max_order: int = MAX_ORDER
                      ) -> RippleJudgement | None:
    """The hold's readings judged with the periodic ripple of the turn removed (module
    docstring); None when they span fewer than MIN_TURNS turns or too few readings to
    fit, and the caller judges sample by sample."""
    import numpy as np  # here, not at load: the axis settings are read without numpy

    v = np.asarray(velocity_dps, dtype=float)
    phi_deg = np.asarray(position_deg, dtype=float)
    if v.size != phi_deg.size or v.size < 3:
        return None
    turns = abs(float(phi_deg[-1] - phi_deg[0])) / 360.0
    if turns < MIN_TURNS:
        return None
    # a few readings per harmonic at least: the fit must not follow the noise
    orders = min(max_order, (v.size - 1) // 8)
    if orders < 1:
        return None
    phi = np.deg2rad(phi_deg)
    h = np.arange(1, orders + 1)
    periodic_basis = np.concatenate([np.cos(np.outer(phi, h)), np.sin(np.outer(phi, h))],
                                    axis=1)
    design = np.concatenate([np.ones((v.size, 1)), periodic_basis], axis=1)
    coef, *_ = np.linalg.lstsq(design, v, rcond=None)
    ripple = periodic_basis @ coef[1:]
    residual = v - ripple - float(target_dps)
    out = np.flatnonzero(np.abs(residual) > tolerance_dps)
    return RippleJudgement(settled=out.size == 0, mean_dps=float(coef[0]),
                           ripple_peak_dps=float(np.max(np.abs(ripple))),
                           worst_residual_dps=float(np.max(np.abs(residual))), turns=turns,
                           orders=int(orders), last_out=int(out[-1]) if out.size else None)


def hold_spans_turns(hold_s: float, rate_dps: float) -> bool:
    """Whether a hold of `hold_s` at `rate_dps` covers MIN_TURNS whole turns."""
    return rate_dps != 0 and math.isfinite(rate_dps) and \
        hold_s * abs(rate_dps) / 360.0 >= MIN_TURNS
