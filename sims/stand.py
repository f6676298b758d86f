"""The simulated stand: the one truth every twin samples.

One `AxisModel` per table axis integrates the axis's angle and rate on the FOG's sample
grid, for whatever rate profile the drive twin commands, with the error sources of the
stand file's `sim:` block (CONTRACT §2): rate bias, harmonics in angle, a mains tone in
time, table rate noise, zero-mark edge jitter, and the FOG's response
`k * w_true + w0 + drift + noise`.

The model is advanced in chunks (`advance_to`), so twins can sample it on the virtual
clock as it runs, and the same code generates an 18 M-sample record in one call. Chunks
are vectorised: the angle equation dphi/dt = w(phi, t) is solved on the sample grid by a
short fixed-point iteration over the cumulative trapezoid (the harmonic term is small,
so each pass shrinks the angle error by a factor ~ 2*pi*amplitude_rel).

Conventions: phi is the unwrapped table angle in its positive sense, deg, 0 at the zero
mark; a zero mark is seen whenever phi crosses a multiple of 360 deg, in either sense.
"""

from __future__ import annotations

import functools
import math
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sims.clock import MAX, SteppedClock, VirtualClock, parse_speed
from sims.rng_grid import RngGrid, pcg64_state, seed_states
from sims.truth import AxisTruth as AxisTruth
from sims.truth import FogTruth as FogTruth
from sims.truth import Harmonic as Harmonic
from sims.truth import Mains as Mains


@dataclass(frozen=True)
class Segment:
    """From t0_s the commanded rate ramps from w0_dps toward target_dps at accel_dps2."""

    t0_s: float
    w0_dps: float
    target_dps: float
    accel_dps2: float

    @property
    def t_end_s(self) -> float:
        if self.accel_dps2 <= 0 or math.isinf(self.accel_dps2):
            return self.t0_s
        return self.t0_s + abs(self.target_dps - self.w0_dps) / self.accel_dps2

    def rate(self, t_s: np.ndarray) -> np.ndarray:
        if self.t_end_s <= self.t0_s:
            return np.full(np.shape(t_s), self.target_dps)
        step = math.copysign(self.accel_dps2, self.target_dps - self.w0_dps)
        # exactly the target once the ramp ends (w0 + a * (t_end - t0) misses it by ~1e-14,
        # and a table at "1e-14 deg/s" would get the noise and mains of a turning one)
        return np.where(t_s >= self.t_end_s, self.target_dps,
                        self.w0_dps + step * (np.minimum(t_s, self.t_end_s) - self.t0_s))


class RateProfile:
    """The commanded rate over time: piecewise constant-acceleration segments.

    A new command starts from the rate the profile has at its time, so a reversal
    mid-ramp is continuous, as a drive's profile generator makes it.
    """

    def __init__(self) -> None:
        self.segments: list[Segment] = [Segment(-math.inf, 0.0, 0.0, math.inf)]

    def command(self, t_s: float, target_dps: float, accel_dps2: float,
                decel_dps2: float | None = None) -> Segment:
        """A drive's profile generator: speed up with accel, slow down with decel.

        A reversal slows to rest with decel, then speeds up the other way with accel (two
        segments). A command may lie in the future (a scheduled stop); any command
        replaces what was scheduled after its time. Returns the last segment.
        """
        decel = accel_dps2 if decel_dps2 is None else decel_dps2
        if accel_dps2 <= 0 or decel <= 0:
            raise ValueError(f"acceleration and deceleration must be > 0, got "
                             f"{accel_dps2}, {decel}")
        self.segments = [s for s in self.segments if s.t0_s <= t_s]
        w_now = float(self.rate(np.array([t_s]))[0])
        target = float(target_dps)
        if w_now != 0.0 and target != 0.0 and (w_now > 0) != (target > 0):
            stop = Segment(t_s, w_now, 0.0, float(decel))
            self.segments.append(stop)
            seg = Segment(stop.t_end_s, 0.0, target, float(accel_dps2))
        elif abs(target) < abs(w_now):
            seg = Segment(t_s, w_now, target, float(decel))
        else:
            seg = Segment(t_s, w_now, target, float(accel_dps2))
        self.segments.append(seg)
        return seg

    def rate(self, t_s: np.ndarray) -> np.ndarray:
        t_s = np.asarray(t_s, dtype=float)
        starts = np.array([s.t0_s for s in self.segments])
        which = np.searchsorted(starts, t_s, side="right") - 1
        if which.size and (which == which.flat[0]).all():  # one segment (most blocks)
            return np.asarray(self.segments[int(which.flat[0])].rate(t_s), dtype=float)
        out = np.empty_like(t_s)
        for i in np.unique(which):
            mask = which == i
            out[mask] = self.segments[i].rate(t_s[mask])
        return out

    def settle_time_s(self) -> float:
        """When the last command reaches its target."""
        return self.segments[-1].t_end_s

    @property
    def target_dps(self) -> float:
        return self.segments[-1].target_dps


@dataclass(frozen=True)
class AxisChunk:
    """Samples n0 .. n0+len-1 of one axis on the FOG grid (t = n / rate_hz)."""

    n0: int
    t_s: np.ndarray
    rate_cmd_dps: np.ndarray
    w_true_dps: np.ndarray
    phi_deg: np.ndarray
    #: the stand's FOG output over the chunk, made when first asked for (`fog_dps`)
    fog_source: Callable[[], np.ndarray] = field(repr=False, compare=False)

    @functools.cached_property
    def fog_dps(self) -> np.ndarray:
        """The FOG's output, drawn only when a twin encodes it: the FOG of the axis not
        under test streams to nobody, and its noise was a third of the stand's draws on
        the paper ladder (issue 62). Its draws are keyed by block (sims/rng_grid.py), so
        drawing them late, or not at all, changes no other number."""
        return self.fog_source()


@dataclass(frozen=True)
class ZeroMarks:
    """Zero-mark crossings: true times, times as the slot sensor's edge shows them, sense."""

    t_true_s: np.ndarray
    t_edge_s: np.ndarray
    sense: np.ndarray  # +1 crossing upward (positive rotation), -1 downward


ChunkListener = Callable[[AxisChunk], None]

_FIXED_POINT_PASSES = 3
#: a fixed-point pass after the first moves phi by a small angle delta (the harmonics'
#: and the bias's integral, ~ amplitude_rel rad): its cos and sin come from the first
#: pass's by rotation, with delta's series to delta^5 (error < delta^6 / 720, 1.4e-15 at
#: this bound; times amplitude_rel in the rate). A larger move is evaluated afresh.
_ROTATE_MAX_RAD = 1.0e-2
#: grid tables of cos/sin(j * step) kept per axis (one per rate the axis turned at lately)
_GRID_TABLES = 4
#: the stand's random-number grid: the draws for samples g*RNG_BLOCK_SAMPLES onward come
#: from a generator keyed by (seed, axis, stream, g). Changing it changes every seeded number.
RNG_BLOCK_SAMPLES = 4096
#: the stand's computation grid (a multiple of RNG_BLOCK_SAMPLES): samples are computed in
#: blocks of this many, each from the state at its start. Larger blocks cost numpy fewer
#: calls per sample (each call holds the interpreter lock the FOG readers also need):
#: 16384 instead of 4096 took the paper ladder's outer 0.1 deg/s pair from 43 to 36 s.
BLOCK_SAMPLES = 16384
#: the grid's streams. "imu" feeds the FOG's channels other than the table axis's (its
#: cross-axis gyros, accelerometers and temperature sensor): a stream of its own, so
#: those draws never move a number of the table, the measured FOG channel or the marks
_STREAMS = {"table": 0, "fog": 1, "edge": 2, "imu": 3}
#: the "imu" stream's channels a sample: the two cross-axis rates, then the accelerometers
#: along the table axis and along the two cross axes
IMU_CHANNELS = 5
#: samples one temperature reading holds: a FOG's temperature sensor is read far more
#: slowly than its frames go out (one draw of the "imu" stream per this many samples)
TEMPERATURE_HOLD_SAMPLES = 64
#: an "imu" draw is a level 0 .. IMU_LEVELS - 1, the sum of four uniform random bytes of
#: the block's generator (Irwin-Hall: a normal's shape within a few per cent, bounded at
#: 3.45 sigma): (level - IMU_LEVEL_MEAN) / IMU_LEVEL_STD is a standard deviate. Levels,
#: not floats: the FOG twin encodes a channel through a table of IMU_LEVELS frame values
#: and their CRC terms, ~0.5 ms a 16384-frame block where normals and a CRC of every
#: field took ~3.5 ms (the paper ladder streams 212 M frames)
IMU_LEVELS = 4 * 255 + 1
IMU_LEVEL_MEAN = 4 * 255 / 2
IMU_LEVEL_STD = math.sqrt(4 * (256**2 - 1) / 12)
#: RNG blocks of the "imu" stream an axis keeps drawn (a reader asks in small chunks)
_IMU_BLOCKS_KEPT = 4
_SEED_CHUNK = 1024        # blocks whose generator seeds are hashed at once (rng_grid.py)


def _part(whole: Callable[[], np.ndarray], lo: int, hi: int) -> Callable[[], np.ndarray]:
    """Samples lo .. hi-1 of a block's FOG output, made when asked for."""
    return lambda: whole()[lo:hi]


@dataclass
class _Block:
    """One block of the grid as computed for the profile of version `version`."""

    k: int
    version: int
    t_s: np.ndarray
    w_cmd: np.ndarray
    w: np.ndarray
    phi: np.ndarray
    fog_of: Callable[[], np.ndarray]   # the FOG output, made on first call (AxisChunk.fog_dps)
    marks: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]  # sample, true, edge, sense


class AxisModel:
    """One table axis and the FOG mounted on it, advanced on the FOG's sample grid.

    Reproducible whatever asks for samples when: samples are computed in fixed blocks of
    `BLOCK_SAMPLES` on the grid, each from the state at the block's start, with random
    numbers drawn from generators keyed by (seed, axis, stream, index of the
    `RNG_BLOCK_SAMPLES` block) (a counter-based scheme, numpy SeedSequence spawn keys).
    Samples are released up to each `advance_to(t)`; a command changes only samples after the last released one,
    and a block computed before the command is computed again: its released prefix comes
    out bit for bit the same (every step of the computation is causal: cumulative sums
    and pointwise terms), so where the chunk boundaries fall (which twin asked, at which
    step of the clock) never changes a number.
    """

    def __init__(self, truth: AxisTruth, rate_hz: float, seed: int | np.random.SeedSequence,
                 name: str = "axis", block_samples: int = BLOCK_SAMPLES) -> None:
        self.name = name
        self.truth = truth
        self.rate_hz = float(rate_hz)
        if truth.mains and truth.mains.amplitude_dps and truth.mains.frequency_hz * 2 >= rate_hz:
            raise ValueError(f"{name}: FOG rate {rate_hz} Hz cannot carry the "
                             f"{truth.mains.frequency_hz} Hz mains tone (Nyquist)")
        self._ss = seed if isinstance(seed, np.random.SeedSequence) \
            else np.random.SeedSequence(seed)
        self._grid = RngGrid(self._ss)
        if block_samples <= 0 or block_samples % RNG_BLOCK_SAMPLES:
            raise ValueError(f"{name}: block_samples must be a positive multiple of "
                             f"{RNG_BLOCK_SAMPLES}, got {block_samples}")
        self.block_samples = int(block_samples)
        self.profile = RateProfile()
        self._profile_version = 0
        self.listeners: list[ChunkListener] = []
        self._n_next = 0  # next grid sample to release
        self._phi_last = 0.0
        self._w_last = 0.0
        self._block_start: tuple[int, float, float] = (0, 0.0, 0.0)  # (k, phi, w) before it
        self._block: _Block | None = None
        self._marks_true: list[np.ndarray] = []
        self._marks_edge: list[np.ndarray] = []
        self._marks_sense: list[np.ndarray] = []
        self.lock = threading.RLock()
        # the harmonics as (order, amplitude_rel, cos phase, sin phase), and the highest
        # order: every order's cos/sin of phi comes from phi's by the complex recurrence
        self._harm = [(h.order, h.amplitude_rel, math.cos(math.radians(h.phase_deg)),
                       math.sin(math.radians(h.phase_deg))) for h in truth.harmonics
                      if h.amplitude_rel]
        self._harm_top = max((order for order, *_ in self._harm), default=0)
        self._grid_tables: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        self._imu_blocks: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._imu_seeds: tuple[int, np.ndarray] | None = None
        self._imu_bits = np.random.PCG64(0)

    # -- time and state -------------------------------------------------------------
    @property
    def t_s(self) -> float:
        """Time of the last generated sample."""
        return (self._n_next - 1) / self.rate_hz

    @property
    def samples_generated(self) -> int:
        return self._n_next

    @property
    def angle_deg(self) -> float:
        return self._phi_last

    @property
    def rate_dps(self) -> float:
        return self._w_last

    def command_rate(self, t_s: float, target_dps: float, accel_dps2: float,
                     decel_dps2: float | None = None) -> Segment:
        """The drive's profile generator: ramp to target from time t_s (RateProfile)."""
        with self.lock:
            self.advance_to(t_s)
            seg = self.profile.command(max(t_s, self.t_s), target_dps, accel_dps2,
                                       decel_dps2)
            self._profile_version += 1
            return seg

    def commanded_rate_at(self, t_s: float) -> float:
        return float(self.profile.rate(np.array([t_s]))[0])

    # -- generation -----------------------------------------------------------------
    def advance_to(self, t_s: float, max_chunk: int = 2_000_000) -> None:
        """Release every grid sample with time <= t_s, in chunks, telling listeners."""
        with self.lock:
            n_end = math.floor(t_s * self.rate_hz + 1e-9) + 1
            B = self.block_samples
            while self._n_next < n_end:
                k = self._n_next // B
                block = self._block_for(k)
                lo = self._n_next - k * B
                hi = min(n_end - k * B, B, lo + max_chunk)
                chunk = AxisChunk(self._n_next, block.t_s[lo:hi], block.w_cmd[lo:hi],
                                  block.w[lo:hi], block.phi[lo:hi],
                                  _part(block.fog_of, lo, hi))
                self._release_marks(block, k * B + lo, k * B + hi)
                self._n_next = k * B + hi
                self._phi_last = float(block.phi[hi - 1])
                self._w_last = float(block.w[hi - 1])
                if hi == B:  # the block is out whole: its end is the next one's start
                    self._block_start = (k + 1, self._phi_last, self._w_last)
                    self._block = None
                for listener in list(self.listeners):
                    listener(chunk)

    def _block_for(self, k: int) -> _Block:
        b = self._block
        if b is not None and b.k == k and b.version == self._profile_version:
            return b
        k0, phi0, w0 = self._block_start
        assert k0 == k, (k0, k)
        self._block = self._generate(k, phi0, w0)
        return self._block

    def _rng_normals(self, stream: str, g: int, n: int) -> np.ndarray:
        """The first n normals of the generator of RNG_BLOCK_SAMPLES-block g of one stream:
        numpy's `default_rng(SeedSequence(entropy, spawn_key=(*axis key, stream, g)))`,
        made without a SeedSequence per block (sims/rng_grid.py)."""
        return self._grid.normals(_STREAMS[stream], g, n)

    def imu_levels(self, n0: int, n: int) -> tuple[np.ndarray, np.ndarray]:
        """The draws of the FOG's other channels at samples n0 .. n0+n-1 (see IMU_LEVELS):
        an (n, IMU_CHANNELS) uint16 array, one row a sample, and the temperature sensor's
        (n,), one draw held for TEMPERATURE_HOLD_SAMPLES samples. From the grid's "imu"
        stream, block by block as every other draw of the stand (where a chunk starts never
        changes a number), and only when asked: a stand whose FOG nobody reads draws none.
        """
        per = RNG_BLOCK_SAMPLES
        rows = np.empty((n, IMU_CHANNELS), dtype=np.uint16)
        temp = np.empty(n, dtype=np.uint16)
        with self.lock:
            at = 0
            while at < n:
                g, lo = divmod(n0 + at, per)
                hi = min(per, lo + n - at)
                block, held = self._imu_block(g)
                rows[at:at + hi - lo] = block[lo:hi]
                temp[at:at + hi - lo] = held[np.arange(lo, hi) // TEMPERATURE_HOLD_SAMPLES]
                at += hi - lo
        return rows, temp

    def _imu_block(self, g: int) -> tuple[np.ndarray, np.ndarray]:
        """RNG block g of the "imu" stream: the raw 64-bit output of the generator numpy
        makes of SeedSequence(entropy, spawn_key=(*axis key, stream, g)) (the grid's
        keying, sims/rng_grid.py), four bytes a draw."""
        got = self._imu_blocks.get(g)
        if got is None:
            per, hold = RNG_BLOCK_SAMPLES, TEMPERATURE_HOLD_SAMPLES
            c = g // _SEED_CHUNK
            if self._imu_seeds is None or self._imu_seeds[0] != c:
                assert self._ss.entropy is not None
                self._imu_seeds = (c, seed_states(
                    self._ss.entropy, (*self._ss.spawn_key, _STREAMS["imu"]),
                    np.arange(c * _SEED_CHUNK, (c + 1) * _SEED_CHUNK)))
            # (numpy types the setter as a private TypedDict; the dict is its shape)
            self._imu_bits.state = pcg64_state(  # type: ignore[assignment]
                self._imu_seeds[1][g - c * _SEED_CHUNK])
            raw = self._imu_bits.random_raw((per * IMU_CHANNELS + per // hold) // 2)
            word = raw.view(np.uint32)   # a draw's four bytes summed in place (SWAR)
            pairs = (word & np.uint32(0x00FF00FF)) + ((word >> np.uint32(8))
                                                      & np.uint32(0x00FF00FF))
            draws = ((pairs & np.uint32(0xFFFF)) + (pairs >> np.uint32(16))).astype(np.uint16)
            got = (draws[:per * IMU_CHANNELS].reshape(per, IMU_CHANNELS),
                   draws[per * IMU_CHANNELS:])
            if len(self._imu_blocks) >= _IMU_BLOCKS_KEPT:
                self._imu_blocks.pop(next(iter(self._imu_blocks)))
            self._imu_blocks[g] = got
        return got

    def _normals(self, stream: str, k: int) -> np.ndarray:
        """Standard normals for every sample of block k, from the random-number grid."""
        per = RNG_BLOCK_SAMPLES
        g0 = k * self.block_samples // per
        return np.concatenate([self._rng_normals(stream, g0 + j, per)
                               for j in range(self.block_samples // per)])

    def _grid_table(self, step_rad: float) -> tuple[np.ndarray, np.ndarray]:
        """cos and sin of j * step_rad for j in [0, block_samples): an angle growing by a
        fixed step on the sample grid (a tone in time, a constant rate) is then
        cos(a0 + j step) = cos a0 cos(j step) - sin a0 sin(j step), two of numpy's
        transcendental calls (19 ns a sample each here) a block instead of a sample."""
        table = self._grid_tables.get(step_rad)
        if table is None:
            j_step = np.arange(self.block_samples) * step_rad
            table = (np.cos(j_step), np.sin(j_step))
            if len(self._grid_tables) >= _GRID_TABLES:
                self._grid_tables.pop(next(iter(self._grid_tables)))
            self._grid_tables[step_rad] = table
        return table

    def _on_grid(self, a0_rad: float, step_rad: float) -> tuple[np.ndarray, np.ndarray]:
        """cos and sin of a0 + j * step over the block, by rotating the grid table."""
        c, s = self._grid_table(step_rad)
        ca, sa = math.cos(a0_rad), math.sin(a0_rad)
        return ca * c - sa * s, sa * c + ca * s

    def _tone(self, n0: int, w_cmd: np.ndarray) -> np.ndarray | None:
        """The mains tone in time while the axis turns (None: no tone), CONTRACT §2:
        amplitude * cos(2 pi f t + phase) at t = n / rate_hz. The same for every pass of
        the fixed point, so computed once a block. The block's phase is taken from the
        integer sample index (2 pi f t itself loses 1e-9 rad to rounding after a day)."""
        m = self.truth.mains
        if not (m and m.amplitude_dps):
            return None
        cycles = m.frequency_hz / self.rate_hz              # tone cycles per sample
        a0 = 2 * math.pi * math.fmod(n0 * cycles, 1.0) + math.radians(m.phase_deg)
        tone = m.amplitude_dps * self._on_grid(a0, 2 * math.pi * cycles)[0]
        return np.where(w_cmd != 0.0, tone, 0.0)

    def _shape(self, cos_phi: np.ndarray, sin_phi: np.ndarray) -> np.ndarray:
        """`AxisTruth.shape_rel` from cos and sin of phi (CONTRACT §2: rate bias plus
        sum a_n cos(n phi + p_n)); cos/sin(n phi) by (c + i s)^n, a multiply a term."""
        out = np.full(cos_phi.shape, self.truth.rate_bias_rel)
        top = self._harm_top
        cn, sn = cos_phi, sin_phi
        for n in range(1, top + 1):
            for order, a, cp, sp in self._harm:
                if order == n:
                    out += a * (cn * cp - sn * sp)     # a cos(n phi + p)
            if n < top:
                cn, sn = cn * cos_phi - sn * sin_phi, sn * cos_phi + cn * sin_phi
        return out

    def _first_angle(self, phi_last: float, w_cmd: np.ndarray, dt: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The fixed point's first guess (harmonics ignored), radians, with its cos and
        sin: at a constant rate (most blocks) from the grid table of its step."""
        w0 = float(w_cmd[0])
        if (w_cmd == w0).all():
            step = math.radians(w0 * dt)
            a0 = math.radians(phi_last) + step
            return (a0 + np.arange(w_cmd.size) * step, *self._on_grid(a0, step))
        theta = np.radians(phi_last + np.cumsum(w_cmd) * dt)
        return theta, np.cos(theta), np.sin(theta)

    def _generate(self, k: int, phi_last: float, w_last: float) -> _Block:
        n = self.block_samples
        n0 = k * n
        idx = np.arange(n0, n0 + n, dtype=np.int64)
        t = idx / self.rate_hz
        w_cmd = self.profile.rate(t)
        turning = w_cmd != 0.0
        noise = np.zeros(n)
        if self.truth.rate_noise_dps and turning.any():  # at rest no draw is used (grid-keyed)
            noise = self._normals("table", k) * self.truth.rate_noise_dps
            noise[~turning] = 0.0
        dt = 1.0 / self.rate_hz
        if w_last == 0.0 and not turning.any():
            # at rest the whole block (every error source is scaled by, or gated on, the
            # commanded rate): the same numbers the solve below gives, without it
            w = np.zeros(n)
            phi = np.full(n, phi_last)
        else:
            # fixed point of phi = phi_last + cumtrapz(w(phi, t)), w = w_cmd (1 + shape)
            # + tone + noise (CONTRACT §2); the first guess ignores harmonics. Each pass
            # after the first moves phi by a small delta: cos/sin of phi by rotating the
            # first pass's through delta (series to delta^5), unless delta is large
            theta, cos_phi, sin_phi = self._first_angle(phi_last, w_cmd, dt)
            tone = self._tone(n0, w_cmd)
            for p in range(_FIXED_POINT_PASSES):
                if p:
                    moved = np.radians(phi)
                    delta = moved - theta
                    if np.abs(delta).max() <= _ROTATE_MAX_RAD:
                        d2 = delta * delta
                        cos_d = 1.0 - d2 * (0.5 - d2 / 24.0)
                        sin_d = delta * (1.0 - d2 * (1.0 / 6.0 - d2 / 120.0))
                        cos_phi, sin_phi = (cos_phi * cos_d - sin_phi * sin_d,
                                            sin_phi * cos_d + cos_phi * sin_d)
                    else:
                        cos_phi, sin_phi = np.cos(moved), np.sin(moved)
                    theta = moved
                w = w_cmd * (1.0 + self._shape(cos_phi, sin_phi))
                if tone is not None:
                    w += tone
                w += noise
                prev = np.concatenate(([w_last], w[:-1]))
                phi = phi_last + np.cumsum(0.5 * (prev + w)) * dt
            if n0 == 0:  # the first sample is the origin, not a step from it
                phi -= 0.5 * (w_last + w[0]) * dt
        fog = self.truth.fog

        @functools.cache
        def fog_of() -> np.ndarray:
            out = fog.k * w + fog.bias_at(t)
            if fog.noise_dps:
                out += self._normals("fog", k) * fog.noise_dps
            return out
        return _Block(k, self._profile_version, t, w_cmd, w, phi, fog_of,
                      self._marks(k, t, phi, phi_last))

    def _marks(self, k: int, t: np.ndarray, phi: np.ndarray, phi_last: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Zero-mark crossings in a block: (sample index after, true time, edge, sense)."""
        dt = 1.0 / self.rate_hz
        t_all = np.concatenate(([t[0] - dt], t))
        phi_all = np.concatenate(([phi_last], phi))
        turn = np.floor(phi_all / 360.0)
        step = np.diff(turn)
        where = np.nonzero(step)[0]
        if k == 0:
            where = where[where > 0]
        # one crossing per step (a step of several turns per sample is impossible here)
        sense = np.sign(step[where])
        mark_phi = np.where(sense > 0, turn[where + 1], turn[where]) * 360.0
        frac = (mark_phi - phi_all[where]) / (phi_all[where + 1] - phi_all[where])
        t_true = t_all[where] + frac * dt
        jitter = self.truth.turn_jitter_s
        sample = k * self.block_samples + where
        t_edge = t_true + (self._edge_normals(sample) * jitter
                           if jitter and t_true.size else 0.0)
        return sample, t_true, np.asarray(t_edge, dtype=float), sense.astype(np.int8)

    def _edge_normals(self, sample: np.ndarray) -> np.ndarray:
        """One normal per zero mark, in order, from the random-number block of its sample."""
        g = sample // RNG_BLOCK_SAMPLES
        out = np.empty(sample.size)
        for gi in np.unique(g).tolist():
            at = g == gi
            out[at] = self._rng_normals("edge", gi, int(at.sum()))
        return out

    def _release_marks(self, block: _Block, n_from: int, n_to: int) -> None:
        sample, t_true, t_edge, sense = block.marks
        keep = (sample >= n_from) & (sample < n_to)
        if keep.any():
            self._marks_true.append(t_true[keep])
            self._marks_edge.append(t_edge[keep])
            self._marks_sense.append(sense[keep])

    def zero_marks(self, t_from_s: float = -math.inf, t_to_s: float = math.inf) -> ZeroMarks:
        """Zero marks whose edge time lies in [t_from_s, t_to_s), from what is generated."""
        with self.lock:
            if not self._marks_true:
                empty = np.empty(0)
                return ZeroMarks(empty, empty, np.empty(0, dtype=np.int8))
            tt = np.concatenate(self._marks_true)
            te = np.concatenate(self._marks_edge)
            ss = np.concatenate(self._marks_sense)
            self._marks_true, self._marks_edge, self._marks_sense = [tt], [te], [ss]
        keep = (te >= t_from_s) & (te < t_to_s)
        return ZeroMarks(tt[keep], te[keep], ss[keep])


@dataclass(frozen=True)
class StandTruth:
    """The whole `sim:` block."""

    seed: int
    axes: dict[str, AxisTruth]
    clock_speed: float = math.inf   # top speed; inf: `max`, as fast as the twins keep up

    @classmethod
    def from_mapping(cls, d: Mapping[str, Any]) -> StandTruth:
        return cls(
            seed=int(d.get("seed", 0)),
            axes={name: AxisTruth.from_mapping(a or {}) for name, a in d.get("axes", {}).items()},
            clock_speed=parse_speed(d.get("clock_speed"), MAX),
        )


class SimulatedStand:
    """The simulated table: its axes and the one virtual clock all twins read."""

    def __init__(self, truth: StandTruth, fog_rate_hz: Mapping[str, float],
                 clock: VirtualClock | SteppedClock | None = None) -> None:
        self.truth = truth
        self.clock = clock or VirtualClock(truth.clock_speed)
        seeds = np.random.SeedSequence(truth.seed).spawn(len(truth.axes))
        self.axes: dict[str, AxisModel] = {
            name: AxisModel(axis, fog_rate_hz.get(name, 1000.0), s, name=name)
            for (name, axis), s in zip(sorted(truth.axes.items()), seeds, strict=True)
        }

    def axis(self, name: str) -> AxisModel:
        try:
            return self.axes[name]
        except KeyError:
            raise KeyError(f"the simulated stand has no axis {name!r} "
                           f"(it has {', '.join(self.axes)})") from None

    def advance(self) -> float:
        """Bring every axis up to the clock's now; returns that time."""
        t = self.clock.now()
        for a in self.axes.values():
            a.advance_to(t)
        return t
