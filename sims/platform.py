"""The simulated gyro platform of docs/method.md B: the truth the drift-pulse twins sample.

A gyro-stabilised platform (the seed paper's figs. 1 and 3) sits on a turntable axis of
the simulated stand. Each of its gyros (x and y horizontal, z vertical if wanted) has a
torque sensor, driven by the pulse generator's voltage through a current amplifier, and
a command angle sensor. The platform angle about a gyro's axis is

    alpha(t) = alpha0 + int (w_own(t) + w_app(t)) dt + int w_c(t) dt       (docs/method.md B)

with w_c = k_ts * i / H (here `precession_dps_per_v` * volts, the + and - polarities of
the current amplifier mismatched by `pulse_mismatch_rel`), w_own the gyro's own drift
(a random walk around its nominal value) and w_app the Earth's rate projected on the
input axis at the platform's heading. The angle sensor reads U = k_as * alpha plus noise.

Time and heading: one time axis, the stand's virtual clock. The platform's heading is
`azimuth_deg` (the X input axis's azimuth, from north, clockwise seen from above, with
the turntable at 0) plus the turntable axis's angle: the model listens to that axis's
chunks, so a 180 deg turn by the drive twin flips the apparent drift (docs/method.md B).
Convention: the turntable's positive sense turns the platform clockwise seen from above.

The slow part (drift) is integrated on a grid of `grid_hz` as the model advances, in
chunks like sims/stand.py; the control precession is exact: the pulse generator's output
is a zero-order hold, so its angle is piecewise linear and its time integral piecewise
quadratic, evaluated in closed form at whatever times (and apertures) a digitizer asks.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

import numpy as np

from drivers.units import ARCSEC_PER_DEG, SECONDS_PER_HOUR
from sims.stand import AxisChunk, AxisModel, SimulatedStand
from sims.truth import HORIZONTAL_OFFSET_DEG as HORIZONTAL_OFFSET_DEG
from sims.truth import VERTICAL_GYROS as VERTICAL_GYROS
from sims.truth import GyroTruth as GyroTruth
from sims.truth import PlatformTruth as PlatformTruth


@dataclass
class _Grid:
    """A growing record of one gyro's drift on the model grid: rate, angle, angle integral."""

    t: list[np.ndarray] = field(default_factory=list)
    w_dps: list[np.ndarray] = field(default_factory=list)
    angle_deg: list[np.ndarray] = field(default_factory=list)
    integral_deg_s: list[np.ndarray] = field(default_factory=list)
    own_dph: list[np.ndarray] = field(default_factory=list)

    def arrays(self) -> tuple[np.ndarray, ...]:
        for name in ("t", "w_dps", "angle_deg", "integral_deg_s", "own_dph"):
            parts = getattr(self, name)
            if len(parts) > 1:
                setattr(self, name, [np.concatenate(parts)])
        return (self.t[0], self.w_dps[0], self.angle_deg[0], self.integral_deg_s[0],
                self.own_dph[0])


class _ControlPulse:
    """One burst of the pulse generator on one gyro: a zero-order-hold precession rate."""

    def __init__(self, knots_s: np.ndarray, rate_dps: np.ndarray) -> None:
        self.knots_s = knots_s                       # n + 1 absolute times
        self.rate_dps = rate_dps                     # n held rates
        dt = np.diff(knots_s)
        self.angle = np.concatenate(([0.0], np.cumsum(rate_dps * dt)))
        self.integral = np.concatenate(
            ([0.0], np.cumsum(self.angle[:-1] * dt + 0.5 * rate_dps * dt * dt)))

    @property
    def t_start_s(self) -> float:
        return float(self.knots_s[0])

    @property
    def t_end_s(self) -> float:
        return float(self.knots_s[-1])

    def angle_and_integral(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Control angle (deg) and its time integral since the burst began (deg s), exact."""
        k = np.clip(np.searchsorted(self.knots_s, t, side="right") - 1,
                    0, self.rate_dps.size - 1)
        u = np.clip(t - self.knots_s[k], 0.0, None)
        inside = t < self.t_end_s
        r = np.where(inside, self.rate_dps[k], 0.0)
        u_in = np.where(inside, u, 0.0)
        a = np.where(inside, self.angle[k] + r * u_in, self.angle[-1])
        s = np.where(inside, self.integral[k] + self.angle[k] * u_in + 0.5 * r * u_in * u_in,
                     self.integral[-1] + self.angle[-1] * (t - self.t_end_s))
        before = t < self.t_start_s
        return np.where(before, 0.0, a), np.where(before, 0.0, s)


class GyroPlatform:
    """The platform: advance it on the stand's clock, drive its torque sensors, read it."""

    def __init__(self, truth: PlatformTruth, stand: SimulatedStand | None = None,
                 grid_hz: float = 100.0) -> None:
        self.truth = truth
        self.stand = stand
        self.clock = stand.clock if stand else None
        self.grid_hz = float(grid_hz)
        self._table: AxisModel | None = None
        if truth.table_axis:
            if stand is None:
                raise ValueError(f"the platform sits on axis {truth.table_axis!r}: "
                                 f"give the simulated stand")
            self._table = stand.axis(truth.table_axis)
            self._table.listeners.append(self._on_table_chunk)
        ss = np.random.SeedSequence([truth.seed, 4])  # 4: not the stand's own streams
        names = sorted(truth.gyros)
        streams = dict(zip(names, ss.spawn(len(names)), strict=True))
        self._rng_noise = {g: np.random.default_rng(streams[g].spawn(1)[0]) for g in names}
        self._rng_walk = {g: np.random.default_rng(streams[g].spawn(1)[0]) for g in names}
        self._rng_jitter = {g: np.random.default_rng(streams[g].spawn(1)[0]) for g in names}
        self._grid = {g: _Grid() for g in names}
        self._last: dict[str, tuple[float, float, float, float]] = {}  # w, angle, integral, own
        self._pulses: dict[str, list[_ControlPulse]] = {g: [] for g in names}
        self._n_next = 0
        self._t_sampled_max = {g: -math.inf for g in names}
        self._heading_buf: list[tuple[np.ndarray, np.ndarray]] = []
        self._buf_lock = threading.Lock()
        self.lock = threading.RLock()

    # -- heading --------------------------------------------------------------------
    def _on_table_chunk(self, chunk: AxisChunk) -> None:
        with self._buf_lock:
            self._heading_buf.append((chunk.t_s, chunk.phi_deg))

    def _table_deg_at(self, t: np.ndarray) -> np.ndarray:
        if self._table is None:
            return np.zeros_like(t)
        with self._buf_lock:
            if not self._heading_buf:  # the table ran ahead before we listened: it is here
                return np.full_like(t, self._table.angle_deg)
            tb = np.concatenate([b[0] for b in self._heading_buf])
            pb = np.concatenate([b[1] for b in self._heading_buf])
            keep = max(int(np.searchsorted(tb, t[-1], side="right")) - 1, 0)
            self._heading_buf = [(tb[keep:], pb[keep:])]  # the rest is history
        heading: np.ndarray = np.interp(t, tb, pb)
        return heading

    @property
    def table_deg(self) -> float:
        """The turntable angle now (0 without a turntable)."""
        return self._table.angle_deg if self._table is not None else 0.0

    @property
    def heading_deg(self) -> float:
        """The X input axis's azimuth now."""
        return self.truth.azimuth_deg + self.table_deg

    # -- the slow part: drift on the grid ---------------------------------------------
    def advance_to(self, t_s: float) -> None:
        """Integrate every gyro's drift on the grid up to t_s (and the turntable first)."""
        with self.lock:
            t_avail = t_s
            if self._table is not None:
                self._table.advance_to(t_s)
                t_avail = min(t_s, self._table.t_s)
            n_end = math.floor(t_avail * self.grid_hz + 1e-9) + 1
            if n_end <= self._n_next:
                return
            t = np.arange(self._n_next, n_end, dtype=np.int64) / self.grid_hz
            table_deg = self._table_deg_at(t)
            for g, truth in self.truth.gyros.items():
                self._advance_gyro(g, truth, t, table_deg)
            self._n_next = n_end

    def _advance_gyro(self, g: str, truth: GyroTruth, t: np.ndarray,
                      table_deg: np.ndarray) -> None:
        h = 1.0 / self.grid_hz
        first = g not in self._last
        w_prev, a_prev, s_prev, own_prev = self._last.get(g, (0.0, 0.0, 0.0,
                                                              truth.own_drift_dph))
        own = np.full(t.size, own_prev)
        if truth.drift_random_walk_dph_per_rth:
            steps = self._rng_walk[g].standard_normal(t.size) * (
                truth.drift_random_walk_dph_per_rth * math.sqrt(h / SECONDS_PER_HOUR))
            if first:
                steps[0] = 0.0  # the run starts at the nominal own drift
            own = own_prev + np.cumsum(steps)
        w = (own + self.truth.apparent_dph(g, table_deg)) / SECONDS_PER_HOUR
        w_before = np.concatenate(([w[0] if first else w_prev], w[:-1]))
        angle = a_prev + np.cumsum(0.5 * (w_before + w) * h)
        if first:
            angle -= 0.5 * (w_before[0] + w[0]) * h  # sample 0 is the origin
        a_before = np.concatenate(([angle[0] if first else a_prev], angle[:-1]))
        integral = s_prev + np.cumsum(0.5 * (a_before + angle) * h)
        if first:
            integral -= 0.5 * (a_before[0] + angle[0]) * h
        grid = self._grid[g]
        grid.t.append(t)
        grid.w_dps.append(w)
        grid.angle_deg.append(angle)
        grid.integral_deg_s.append(integral)
        grid.own_dph.append(own)
        self._last[g] = (float(w[-1]), float(angle[-1]), float(integral[-1]), float(own[-1]))

    def _drift_angle(self, g: str, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Drift angle (deg) and its integral (deg s) at times t, from the grid."""
        tg, wg, ag, sg, _ = self._grid[g].arrays()
        h = 1.0 / self.grid_hz
        k = np.clip(np.floor(t * self.grid_hz).astype(np.int64), 0, tg.size - 1)
        last = k >= tg.size - 1
        k_in = np.minimum(k, tg.size - 2) if tg.size > 1 else k
        u = t - tg[k]
        if tg.size > 1:
            slope = (ag[k_in + 1] - ag[k_in]) / h
        else:
            slope = wg[k]
        slope = np.where(last, wg[k], slope)   # past the grid: the last drift rate
        a = ag[k] + slope * u
        s = sg[k] + ag[k] * u + 0.5 * slope * u * u
        return a, s

    # -- the fast part: the torque sensor's pulses -----------------------------------
    def apply_voltage(self, gyro: str, t0_s: float, sample_interval_s: float,
                      volts: np.ndarray) -> None:
        """The pulse generator's output on a gyro's torque sensor from t0 (zero-order hold).

        Each run of one sign is a pulse; its edges get the truth's timing jitter, and the
        negative polarity the current amplifier's mismatch (docs/method.md B error sources).
        """
        truth = self.truth.gyros[gyro]
        v = np.asarray(volts, dtype=float)
        if v.ndim != 1 or v.size == 0:
            raise ValueError("the pulse waveform must be a non-empty 1-D array")
        with self.lock:
            if t0_s < self._t_sampled_max[gyro]:
                raise RuntimeError(f"pulse on gyro {gyro} at t = {t0_s:.6f} s starts before "
                                   f"the time its angle sensor was already read "
                                   f"(t = {self._t_sampled_max[gyro]:.6f} s): causality")
            n = v.size
            sign = np.sign(v)
            edges = np.concatenate(([0], np.nonzero(np.diff(sign))[0] + 1, [n]))
            jitter = np.zeros(edges.size)
            if truth.pulse_jitter_s:
                jitter = self._rng_jitter[gyro].standard_normal(edges.size) * truth.pulse_jitter_s
            knots = t0_s + np.interp(np.arange(n + 1), edges,
                                     edges * sample_interval_s + jitter)
            gain = np.where(v < 0, 1.0 + truth.pulse_mismatch_rel, 1.0)
            rate = truth.precession_dps_per_v * v * gain  # docs/method.md B: w_c = k_ts i / H
            self._pulses[gyro].append(_ControlPulse(knots, rate))

    def _control_angle(self, g: str, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        a = np.zeros_like(t)
        s = np.zeros_like(t)
        t_lo, t_hi = float(t.min()), float(t.max())
        for p in self._pulses[g]:
            if t_hi < p.t_start_s:
                continue
            if t_lo >= p.t_end_s:  # over: its angle stays
                a += p.angle[-1]
                s += p.integral[-1] + p.angle[-1] * (t - p.t_end_s)
                continue
            pa, ps = p.angle_and_integral(t)
            a += pa
            s += ps
        return a, s

    # -- the angle sensor --------------------------------------------------------------
    def sample_u(self, gyro: str, t_s: np.ndarray | float, aperture_s: float = 0.0
                 ) -> np.ndarray:
        """The angle sensor's output U = k_as * alpha + noise (V), docs/method.md B.

        With an aperture, each value is the mean of U over [t, t + aperture], as an
        integrating digitizer reports it; the noise is per value.
        """
        truth = self.truth.gyros[gyro]
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        if t.size == 0:
            return np.empty(0)
        with self.lock:
            t_end = float(t.max()) + aperture_s
            self.advance_to(t_end)
            self._t_sampled_max[gyro] = max(self._t_sampled_max[gyro], t_end)
            if aperture_s > 0:
                _, s0 = self._drift_angle(gyro, t)
                _, s1 = self._drift_angle(gyro, t + aperture_s)
                _, c0 = self._control_angle(gyro, t)
                _, c1 = self._control_angle(gyro, t + aperture_s)
                alpha = (s1 - s0 + c1 - c0) / aperture_s
            else:
                alpha = self._drift_angle(gyro, t)[0] + self._control_angle(gyro, t)[0]
            alpha = alpha + truth.angle_offset_deg
            u: np.ndarray = truth.k_as_v_per_deg * alpha
            if truth.angle_noise_arcsec:
                u += self._rng_noise[gyro].standard_normal(t.size) * (
                    truth.k_as_v_per_deg * truth.angle_noise_arcsec / ARCSEC_PER_DEG)
        return u

    # -- truth for tests -----------------------------------------------------------------
    def own_drift_dph(self, gyro: str, t_from_s: float | None = None,
                      t_to_s: float | None = None) -> float:
        """The own drift: nominal; at t_from; or its mean over [t_from, t_to] (random walk)."""
        if t_from_s is None:
            return self.truth.gyros[gyro].own_drift_dph
        t_to = t_from_s if t_to_s is None else t_to_s
        with self.lock:
            self.advance_to(t_to)
            tg, _, _, _, own = self._grid[gyro].arrays()
        sel = (tg >= t_from_s) & (tg <= t_to)
        if sel.sum() < 2:
            return float(np.interp(0.5 * (t_from_s + t_to), tg, own))
        return float(own[sel].mean())
