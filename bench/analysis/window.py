"""One half of a +/- pair: whole turns timed by the counter and the FOG samples over them.

API
    HalfRecord(sign, edge_times_s, fog_t_s, fog_dps)     # what the engine hands in
    Window.from_record(rec, index, chunk=...) -> Window    # exact integrals over whole turns

The FOG arrays may run past the timed turns (ramps, settling); only samples inside
[t_0, t_N] count, and the integral of the FOG over [t_0, t_j] is taken exactly for the
linear interpolant between samples, so a window's FOG mean is over exactly the turns the
counter timed (docs/method.md A3) whatever the edges' position between samples. Gaps (dropped
frames) are allowed: the trapezoid spans them.

The arrays are not copied: slices are views, and every pass over samples runs in chunks,
so the analysis never holds more than a few chunk-sized temporaries. The FOG arrays may
be DiskArrays (disk.py): a record of any length is then read from its file chunk by
chunk, with the same values and so the same result.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import cast

import numpy as np

from bench.analysis.disk import DiskArray, Samples, as_samples, searchsorted
from bench.analysis.turns import check_edges

DEFAULT_CHUNK = 1 << 16
# relative tolerance on a uniform grid: t[b] - t[a] == (b - a) * dt
_UNIFORM_TOL = 1e-6


@dataclass(frozen=True, eq=False)
class HalfRecord:
    """One window of whole turns at one commanded rate: sign +1 or -1 of the command,
    the zero-mark edge times bounding the timed turns (N + 1 edges for N turns), and the
    FOG's samples (time s on the stand's time axis, rate deg/s as the FOG reports it)."""

    sign: int
    edge_times_s: np.ndarray
    fog_t_s: Samples
    fog_dps: Samples
    # the session (bench run or --resume) that acquired it: each session has a time axis
    # and a FOG bias of its own (a resumed pair, pair.py)
    session: int = 0


def _partial(t: Samples, f: Samples, p: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Integral of the linear interpolant from sample p to time x (t_p <= x <= t_p+1)."""
    dx = x - t[p]
    nxt = np.minimum(p + 1, t.size - 1)
    span = t[nxt] - t[p]
    slope = np.where(span > 0, (f[nxt] - f[p]) / np.where(span > 0, span, 1.0), 0.0)
    return cast(np.ndarray, dx * f[p] + 0.5 * dx * dx * slope)


@dataclass(frozen=True, eq=False)
class Window:
    """A HalfRecord reduced to what the analysis needs (all integrals of the raw FOG)."""

    index: int
    sign: int
    edges_s: np.ndarray        # N + 1 edge times
    t: np.ndarray | DiskArray  # full FOG time array (view of the record's, or on disk)
    f: np.ndarray | DiskArray  # full FOG rate array
    s_lo: int                  # first sample with t >= t_0
    s_hi: int                  # one past the last sample with t <= t_N
    turn_start: np.ndarray     # N + 1 sample indices: turn j is [turn_start[j], turn_start[j+1])
    edge_int: np.ndarray       # N + 1 integrals of the FOG from t_0 to each edge, deg
    i_first: float             # integral from t_0 to the first sample in the window
    uniform_dt_s: float | None  # the grid step when samples are evenly spaced, else None

    @property
    def turns(self) -> int:
        return self.edges_s.size - 1

    @property
    def duration_s(self) -> float:
        return float(self.edges_s[-1] - self.edges_s[0])

    @property
    def t_centre_s(self) -> float:
        return float(0.5 * (self.edges_s[0] + self.edges_s[-1]))

    @property
    def n_samples(self) -> int:
        return self.s_hi - self.s_lo

    @property
    def fog_mean_dps(self) -> float:
        """Time-mean of the FOG over exactly the timed turns (docs/method.md A3)."""
        return float(self.edge_int[-1] / self.duration_s)

    @property
    def turn_periods_s(self) -> np.ndarray:
        return np.diff(self.edges_s)

    @property
    def turn_fog_mean_dps(self) -> np.ndarray:
        return cast(np.ndarray, np.diff(self.edge_int) / self.turn_periods_s)

    @property
    def turn_centres_s(self) -> np.ndarray:
        return cast(np.ndarray, 0.5 * (self.edges_s[:-1] + self.edges_s[1:]))

    @property
    def turn_samples(self) -> np.ndarray:
        return np.diff(self.turn_start)

    @classmethod
    def from_record(cls, rec: HalfRecord, index: int, chunk: int = DEFAULT_CHUNK) -> Window:
        what = f"half {index}"
        if rec.sign not in (1, -1):
            raise ValueError(f"{what}: sign must be +1 or -1, got {rec.sign!r}")
        e = check_edges(rec.edge_times_s, what)
        t = as_samples(rec.fog_t_s)   # a DiskArray stays on disk (disk.py)
        f = as_samples(rec.fog_dps)
        if t.ndim != 1 or t.shape != f.shape:
            raise ValueError(f"{what}: fog_t_s and fog_dps must be 1-D of equal length "
                             f"(got {t.shape} and {f.shape})")
        if t.size < 2 or not (t[0] <= e[0] and t[-1] >= e[-1]):
            lo, hi = (t[0], t[-1]) if t.size else (math.nan, math.nan)
            raise ValueError(f"{what}: FOG samples [{lo:.6f}, {hi:.6f}] s do not cover the "
                             f"timed turns [{e[0]:.6f}, {e[-1]:.6f}] s")
        s_lo = int(searchsorted(t, e[0], "left"))
        s_hi = int(searchsorted(t, e[-1], "right"))
        starts = searchsorted(t, e, "left")
        starts[-1] = s_hi
        if np.any(np.diff(starts) <= 0):
            raise ValueError(f"{what}: a turn holds no FOG sample (FOG rate too low for "
                             "this table rate?)")
        a = max(s_lo - 1, 0)
        b = min(s_hi, t.size - 1)
        span = t[b] - t[a]
        dt = span / (b - a) if b > a else 0.0
        uniform = (dt if dt > 0 and abs(span - (b - a) * dt) <= _UNIFORM_TOL * dt
                   and _grid_ok(t, a, b, dt) else None)
        # cumulative trapezoid from sample s_lo up to the last sample <= each edge
        p_edge = searchsorted(t, e, "right") - 1
        cum = _cumtrapz_at(t, f, s_lo, np.maximum(p_edge, s_lo), chunk)
        i_first = 0.0          # integral from t_0 to the first sample inside the window
        if s_lo > 0 and t[s_lo] > e[0]:
            p0 = np.array([s_lo - 1])
            i_first = float(_partial(t, f, p0, t[s_lo:s_lo + 1])[0]
                            - _partial(t, f, p0, e[:1])[0])
        # integral t_0 -> t_{p_j} is i_first + cum_j (p_j >= s_lo); then the part to t_j
        to_edge = _partial(t, f, np.maximum(p_edge, s_lo), e)
        edge_int = i_first + cum + to_edge
        # an edge before the window's first sample (only edge 0) has no in-window part
        before = p_edge < s_lo
        edge_int[before] = 0.0
        edge_int[0] = 0.0
        if not np.all(np.isfinite(edge_int)):
            raise ValueError(f"{what}: FOG samples in [{e[0]:.3f}, {e[-1]:.3f}] s are not "
                             "all finite (NaN or inf)")
        return cls(index=index, sign=int(rec.sign), edges_s=e, t=t, f=f, s_lo=s_lo,
                   s_hi=s_hi, turn_start=starts.astype(np.int64), edge_int=edge_int,
                   i_first=i_first, uniform_dt_s=uniform)


def _grid_ok(t: Samples, a: int, b: int, dt: float) -> bool:
    """Spot-check a few interior samples against the grid (cheap, O(1))."""
    probe = np.linspace(a, b, 17).astype(np.int64)
    return bool(np.all(np.abs(t[probe] - (t[a] + (probe - a) * dt)) <= 1e-3 * dt))


def _cumtrapz_at(t: Samples, f: Samples, start: int, idx: np.ndarray,
                 chunk: int) -> np.ndarray:
    """Trapezoid integral from sample `start` to each sample in sorted `idx`, in chunks."""
    out = np.zeros(idx.size)
    order = np.argsort(idx, kind="stable")
    targets = idx[order]
    carry = 0.0
    k = 0
    n_end = int(targets[-1]) if targets.size else start
    c0 = start
    while k < targets.size and targets[k] <= start:
        out[order[k]] = 0.0
        k += 1
    while c0 < n_end and k < targets.size:
        c1 = min(c0 + chunk, n_end)
        tt = t[c0:c1 + 1]
        ff = f[c0:c1 + 1]
        areas = 0.5 * (ff[:-1] + ff[1:]) * np.diff(tt)   # area j spans samples c0+j, c0+j+1
        # targets in (c0, c1]: sum of areas[: target - c0]
        k_end = int(np.searchsorted(targets, c1, "right"))
        if k_end > k:
            cs = np.cumsum(areas)
            out[order[k:k_end]] = carry + cs[targets[k:k_end] - c0 - 1]
            carry += float(cs[-1])
        else:
            carry += float(areas.sum())
        k = k_end
        c0 = c1
    return out
