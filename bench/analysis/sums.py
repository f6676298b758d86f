"""The one pass over the FOG samples: sufficient statistics for docs/method.md A4 and A5.

API
    Design(harmonics, mains_hz, fine_bin_deg=1.0)
    accumulate(win, cal, design, chunk=...) -> WindowSums
    residual_differences(sums, coef, max_samples) -> (sum_d2, pairs)

Why sums and not arrays: an 18 M-sample record does not need 18 M-row design matrices.
The linear model of the raw FOG in one window,

    f = c + e * tau + [mc cos(2 pi f_m t) + ms sin(2 pi f_m t)]
          + sum_h (ac_h cos(h phi) + as_h sin(h phi)),      tau = (t - t_centre) / (D / 2)

(docs/method.md A4: harmonics of the angle plus a tone in time; c and e absorb the FOG's bias
and its drift), is fitted from its Gram matrix [A y]^T [A y], built chunk by chunk. The
residual sum of squares for any coefficient vector follows from the same matrix, so the
random part of docs/method.md A5 needs no second pass. Sums of (1, tau, y, mains) over fine
angle bins (1 deg by default, aligned with each turn's zero mark) give the paper's binned
estimator, the random part averaged over angles, and block sums for a noise estimate robust
to coloured noise. A bin's harmonic content comes from its centre angle (with the sinc
factor of the bin's width), exact to second order in the bin width.

Rows of the design buffer: 0 const, 1 tau, 2 y (raw FOG minus a centring constant),
3-4 mains cos/sin (if a mains frequency is given), then cos/sin of phi, 2 phi, ... H phi.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from bench.analysis.angle import FogCalibration, step_integral, turn_fraction
from bench.analysis.window import DEFAULT_CHUNK, Window

ROW_CONST, ROW_TAU, ROW_Y = 0, 1, 2
TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class Design:
    """What the systematic model contains."""

    harmonics: int = 4
    mains_hz: float | None = 50.0
    fine_bin_deg: float = 1.0

    def __post_init__(self) -> None:
        if self.harmonics < 0:
            raise ValueError(f"harmonics must be >= 0, got {self.harmonics}")
        nb = 360.0 / self.fine_bin_deg
        if self.fine_bin_deg <= 0 or abs(nb - round(nb)) > 1e-9:
            raise ValueError(f"fine_bin_deg must divide 360, got {self.fine_bin_deg}")
        if self.mains_hz is not None and not self.mains_hz > 0:
            raise ValueError(f"mains_hz must be > 0 or None, got {self.mains_hz}")

    @property
    def has_mains(self) -> bool:
        return self.mains_hz is not None

    @property
    def bins_per_turn(self) -> int:
        return round(360.0 / self.fine_bin_deg)

    @property
    def bin_rows(self) -> int:
        """Rows summed per fine bin: const, tau, y and the mains pair."""
        return 5 if self.has_mains else 3

    @property
    def row_mains(self) -> int:
        return 3

    @property
    def row_harm(self) -> int:
        return self.bin_rows

    @property
    def rows(self) -> int:
        return self.bin_rows + 2 * self.harmonics

    def model_rows(self) -> list[int]:
        """Every row but y: the columns of the design matrix."""
        return [r for r in range(self.rows) if r != ROW_Y]


@dataclass(frozen=True, eq=False)
class WindowSums:
    """Sufficient statistics of one window."""

    win: Window
    cal: FogCalibration       # the calibration the angles were computed with
    design: Design
    y_centre_dps: float       # subtracted from the raw FOG before squaring
    gram: np.ndarray          # rows x rows, [A y]^T [A y] in the buffer's row order
    bins: np.ndarray          # bin_rows x (turns * bins_per_turn): sums per fine bin
    chunk: int                # the chunk length of the pass
    chunk_i0: np.ndarray      # raw FOG integral from t_0 to each chunk's first sample

    @property
    def n(self) -> int:
        return int(round(self.gram[ROW_CONST, ROW_CONST]))

    def bin_centres_deg(self) -> np.ndarray:
        """The table angle at each fine bin's centre (decreasing for a negative rotation)."""
        nb = self.design.bins_per_turn
        u = (np.arange(nb) + 0.5) / nb
        phi = 360.0 * (u if self.win.sign > 0 else 1.0 - u)
        return np.tile(phi, self.win.turns)


class _Pass:
    """Per-window state of a pass: buffers, the mains phasor table, integral carry."""

    def __init__(self, win: Window, cal: FogCalibration, design: Design, chunk: int,
                 y_centre: float) -> None:
        self.win, self.cal, self.design = win, cal, design
        self.y_centre = y_centre
        m = min(chunk, win.n_samples)
        self.buf = np.empty((design.rows, m))
        self.buf[ROW_CONST] = 1.0
        self.tmp = np.empty(m)
        self.tmp32 = np.empty(m, dtype=np.float32)
        self.tab = None
        if design.has_mains and win.uniform_dt_s is not None:
            # uniform grid: cos/sin(w (t0 + j dt)) by rotating a table, no trig per sample
            assert design.mains_hz is not None  # has_mains
            arg = TWO_PI * design.mains_hz * win.uniform_dt_s * np.arange(m)
            self.tab = (np.cos(arg), np.sin(arg))
        nb = design.bins_per_turn
        self.bin_edges_u = np.arange(1, nb) / nb

    def fill(self, c0: int, c1: int, i_c0: float) -> tuple[np.ndarray, np.ndarray,
                                                         np.ndarray]:
        """Fill buf[:, :c1-c0]; return the raw integral and the chunk's fine bins as
        (first sample of each non-empty bin, relative to c0; its global bin id)."""
        win, design, buf = self.win, self.design, self.buf
        m = c1 - c0
        t = win.t[c0:c1]
        u, segs, i_raw = turn_fraction(win, self.cal, c0, c1, i_c0)
        np.subtract(t, win.t_centre_s, out=buf[ROW_TAU, :m])
        buf[ROW_TAU, :m] *= 2.0 / win.duration_s
        np.subtract(win.f[c0:c1], self.y_centre, out=buf[ROW_Y, :m])
        if design.has_mains:
            self._mains(t, buf[design.row_mains, :m], buf[design.row_mains + 1, :m])
        if design.harmonics:
            self._harmonics(u, m)
        return (i_raw, *self._bins(u, segs))

    def _mains(self, t: np.ndarray, mc: np.ndarray, ms: np.ndarray) -> None:
        assert self.design.mains_hz is not None  # only called when has_mains
        w = TWO_PI * self.design.mains_hz
        m = t.size
        if self.tab is not None:
            ph0 = math.fmod(w * float(t[0]), TWO_PI)
            c, s = math.cos(ph0), math.sin(ph0)
            tc, ts = self.tab[0][:m], self.tab[1][:m]
            tmp = self.tmp[:m]
            np.multiply(tc, c, out=mc)
            np.multiply(ts, s, out=tmp)
            mc -= tmp
            np.multiply(tc, s, out=ms)
            np.multiply(ts, c, out=tmp)
            ms += tmp
            return
        ph = np.multiply(t, w)
        np.mod(ph, TWO_PI, out=ph)
        ph32 = ph.astype(np.float32)
        mc[:] = np.cos(ph32)
        ms[:] = np.sin(ph32)

    def _harmonics(self, u: np.ndarray, m: int) -> None:
        buf, r = self.buf, self.design.row_harm
        th = self.tmp32[:m]
        np.multiply(u, TWO_PI, out=th, casting="same_kind")
        c1_, s1_ = buf[r, :m], buf[r + 1, :m]
        c1_[:] = np.cos(th)
        s1_[:] = np.sin(th)
        if self.win.sign < 0:  # phi = 360 (1 - u): cos(h phi) = cos(h th), sin(h phi) = -sin
            np.negative(s1_, out=s1_)
        tmp = self.tmp[:m]
        for h in range(2, self.design.harmonics + 1):
            pc, ps = buf[r + 2 * (h - 2), :m], buf[r + 2 * (h - 2) + 1, :m]
            oc, os_ = buf[r + 2 * (h - 1), :m], buf[r + 2 * (h - 1) + 1, :m]
            np.multiply(pc, c1_, out=oc)
            np.multiply(ps, s1_, out=tmp)
            oc -= tmp
            np.multiply(ps, c1_, out=os_)
            np.multiply(pc, s1_, out=tmp)
            os_ += tmp

    def _bins(self, u: np.ndarray, segs: list[tuple[int, int, int]]
              ) -> tuple[np.ndarray, np.ndarray]:
        """Fine bins by bisection of u inside each turn segment (u rises through a turn;
        where noise makes it step back near a bin edge, the running maximum of the
        boundaries keeps the bins contiguous)."""
        nb = self.design.bins_per_turn
        starts, ids = [], []
        for j, a, b in segs:
            pos = np.empty(nb + 1, dtype=np.int64)
            pos[0], pos[nb] = a, b
            pos[1:nb] = a + np.searchsorted(u[a:b], self.bin_edges_u)
            np.maximum.accumulate(pos, out=pos)
            full = np.flatnonzero(pos[1:] > pos[:-1])
            starts.append(pos[full])
            ids.append(j * nb + full)
        return np.concatenate(starts), np.concatenate(ids)


def _chunks(win: Window, chunk: int) -> Iterator[tuple[int, int]]:
    c0 = win.s_lo
    while c0 < win.s_hi:
        c1 = min(c0 + chunk, win.s_hi)
        yield c0, c1
        c0 = c1


def accumulate(win: Window, cal: FogCalibration, design: Design,
               chunk: int = DEFAULT_CHUNK) -> WindowSums:
    """One pass over the window's samples."""
    rows = design.rows
    gram = np.zeros((rows, rows))
    bins = np.zeros((design.bin_rows, win.turns * design.bins_per_turn))
    y_centre = win.fog_mean_dps
    ps = _Pass(win, cal, design, chunk, y_centre)
    i_c0 = win.i_first
    chunk_i0 = []
    for c0, c1 in _chunks(win, chunk):
        m = c1 - c0
        chunk_i0.append(i_c0)
        i_raw, starts, ids = ps.fill(c0, c1, i_c0)
        if c1 < win.s_hi:
            i_c0 = float(i_raw[-1]) + step_integral(win, c1 - 1)
        b = ps.buf if m == ps.buf.shape[1] else ps.buf[:, :m]
        gram += b @ b.T
        bins[:, ids] += np.add.reduceat(b[:design.bin_rows], starts, axis=1)
    if not np.all(np.isfinite(gram)):
        raise ValueError(f"half {win.index}: FOG samples in [{win.edges_s[0]:.3f}, "
                         f"{win.edges_s[-1]:.3f}] s are not all finite (NaN or inf)")
    return WindowSums(win=win, cal=cal, design=design, y_centre_dps=y_centre, gram=gram,
                      bins=bins, chunk=chunk, chunk_i0=np.array(chunk_i0))


def residual_differences(ws: WindowSums, coef: np.ndarray, max_samples: int
                         ) -> tuple[float, int]:
    """Sum of squared successive differences of the fit residual, and their count.

    Run on evenly spaced chunks holding about max_samples samples: the white noise at the
    sample rate needs far fewer samples than the record has (docs/method.md A5 floor).
    `coef` is the fitted coefficient of every buffer row (0 for y).
    """
    win, design, chunk = ws.win, ws.design, ws.chunk
    spans = list(_chunks(win, chunk))
    step = max(1, math.ceil(len(spans) * chunk / max(max_samples, chunk)))
    ps = _Pass(win, ws.cal, design, chunk, ws.y_centre_dps)
    c = coef.copy()
    c[ROW_Y] = 0.0
    total, pairs = 0.0, 0
    for i in range(0, len(spans), step):
        c0, c1 = spans[i]
        m = c1 - c0
        ps.fill(c0, c1, float(ws.chunk_i0[i]))
        b = ps.buf[:, :m]
        r = b[ROW_Y] - c @ b
        d = np.diff(r)
        total += float(d @ d)
        pairs += d.size
    return total, pairs
