"""The FOG twin's frames: the stand's samples of the measured axis and the unit's other
channels (cross-axis rates, accelerations, temperature) encoded as the configured frame
format, with the injected faults, and queued for the line (sims/fog_line.py).

The block of stand samples the axis hands its listeners (`_on_chunk`) is encoded here and
nowhere else: the sample model and its speed live in this module.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drivers.fog_formats import FixedFieldsEncoder
from drivers.kvh_config import FEET_PER_METER, G0_MPS2
from sims.fog_faults import Corrupt, Drop, Fault, Garbage, Hold, Stall
from sims.fog_line import FogLine
from sims.stand import (
    IMU_CHANNELS,
    IMU_LEVEL_MEAN,
    IMU_LEVEL_STD,
    IMU_LEVELS,
    TEMPERATURE_HOLD_SAMPLES,
    AxisChunk,
)

#: the accelerometers' noise, g rms a sample. An assumption of the twin: the stand file
#: says nothing of the accelerometers and the ICD pages we read give no figure
ACCEL_NOISE_G = 5e-4
#: the temperature sensor (deg C): the unit warms from the ambient by WARM_UP_C with the
#: time constant WARM_UP_TAU_S from power-on (stand time 0), read with this noise. The
#: frame carries whole degrees (ICD Table 5-2), so a short record reads the ambient
WARM_UP_C = 1.0
WARM_UP_TAU_S = 1200.0
TEMPERATURE_NOISE_C = 0.05
#: co-simulation: stand samples released to the twin and kept to be encoded together, up
#: to this many (or until its frames are to be read: `settled`). A drive's settle steps
#: the clock every 50 ms of stand time, 50 samples at 1 kHz, and encoding them block by
#: block cost ~0.2 ms of fixed numpy overhead a call (issue 62); the frames are the same
#: bytes (every field and the CRC are a frame's own; the other channels' draws are keyed
#: by stand sample, sims/stand.py imu_levels)
DEFER_SAMPLES = 16384


@dataclass(frozen=True)
class _Tables:
    """FogTwin._tables: what encoding a frame needs for one set of the unit's settings."""

    key: tuple[object, ...]
    encoder: FixedFieldsEncoder    # the measured field and the counter; the rest 0
    fields: list[str]              # the other channels' fields (FogTwin._side_fields)
    values: np.ndarray             # (IMU_CHANNELS, IMU_LEVELS) float32, frame units
    terms: np.ndarray              # (IMU_CHANNELS, IMU_LEVELS) uint32: their CRC terms
    temperature: np.ndarray        # (65536,) uint32: the temperature field's, by its bits



class FogSamples(FogLine):
    """Stand samples to frames: the encoding, the =DR decimation, the faults, the truth."""

    #: set by FogTwin.__init__ (sims/fog_twin.py)
    _col: int
    #: the frame's other two rotational (and linear) fields: the cross axes
    _cross: list[int]
    _carry: list[tuple[np.ndarray, ...]]
    _tables_now: _Tables | None
    _temperature_terms: dict[str, np.ndarray]
    #: the ambient the unit's temperature starts from, deg C (it warms up: _side)
    temperature: float
    keep_truth: bool
    _faults: list[Fault]
    _next_sample: int
    _truth: list[tuple[np.ndarray, ...]]
    frames_encoded: int
    #: co-simulation: released chunks not yet encoded (DEFER_SAMPLES), and their samples
    _pending: list[AxisChunk]
    _pending_n: int

    def _side(self, n0: int, n: int) -> tuple[np.ndarray, np.ndarray]:
        """The unit's channels other than the measured one at stand samples n0..n0+n-1:
        their draws, (n, IMU_CHANNELS) levels (AxisModel.imu_levels: the two cross-axis
        rates, the accelerations along the table axis and across it; `_side_values` makes
        them deg/s and g), and the temperature (n,) deg C.

        The FOG's sensitive axis is along the table axis, vertical: the cross-axis gyros
        read white noise at the FOG's own noise level (the earth rate's horizontal part,
        ~0.004 deg/s times the cosine of the latitude, is left out: the stand states no
        latitude), the accelerometers +1 g along the axis (ICD Table 9 note 4: +1 g with
        the positive axis up) and 0 g across it, with ACCEL_NOISE_G, and the temperature
        sensor the ambient, warming by WARM_UP_C with WARM_UP_TAU_S from power-on. The
        draws are the stand's own stream, so the z channel and every other number of the
        stand stay bit for bit what they were.
        """
        levels, temp_levels = self.axis.imu_levels(n0, n)
        hold = TEMPERATURE_HOLD_SAMPLES           # a reading holds, taken at its start
        h = np.arange(n0, n0 + n) // hold
        t_s = np.arange(h[0], h[-1] + 1) * (hold / self.rate_hz)
        warm = self.temperature - WARM_UP_C * np.expm1(-t_s / WARM_UP_TAU_S)
        temp = warm[h - h[0]] \
            + TEMPERATURE_NOISE_C / IMU_LEVEL_STD * (temp_levels - IMU_LEVEL_MEAN)
        return levels, temp

    def _side_values(self, levels: np.ndarray) -> np.ndarray:
        """(m, IMU_CHANNELS) levels as deg/s (the cross-axis rates) and g (the rest)."""
        step = np.array([self.axis.truth.fog.noise_dps] * 2 + [ACCEL_NOISE_G] * 3) \
            / IMU_LEVEL_STD
        values: np.ndarray = (levels - IMU_LEVEL_MEAN) * step
        values[:, 2] += 1.0                       # +1 g along the (vertical) table axis
        return values

    def _in_frame_units(self, values: np.ndarray) -> np.ndarray:
        """`_side_values` (deg/s, g; a frame's sum or mean) in the frame's units: the
        rotational ones (ROTFMT/ROTUNITS) and the linear ones (LINFMT: g, or the delta
        velocity over the frame in m/s or ft/s)."""
        out = values.astype(np.float64)
        out[:, :2] /= self._dps_per_unit
        if self.lin_format != "ACCEL":
            out[:, 2:] *= G0_MPS2 / self.data_rate_hz * (
                FEET_PER_METER if self.lin_units == "FEET" else 1.0)
        return out

    def _side_fields(self) -> list[str]:
        """The frame fields of the IMU_CHANNELS channels, in their order."""
        lin = ("ax", "ay", "az")
        a, b = self._cross
        return [self.format.rate_fields[a], self.format.rate_fields[b],
                lin[self._col], lin[a], lin[b]]

    def _temperature_field(self, temp_c: np.ndarray) -> np.ndarray:
        """Whole degrees C or F (TEMPUNITS; Table 5-2: INT16)."""
        return np.rint(temp_c if self.temp_units == "C" else temp_c * 9 / 5 + 32
                       ).astype(np.int16)

    def _tables(self) -> _Tables:
        """For the settings now: the encoder of the measured field and the counter (its
        template's other fields 0), every level's frame value of each other channel and
        its term of the CRC (the CRC is affine: a field put into a frame whose field was 0
        adds its own term, drivers/fog_formats.py Crc32), and the temperature's terms."""
        f = self.format
        key = (f.name, self._col, self.units, self.lin_format, self.lin_units,
               self.data_rate_hz, self.axis.truth.fog.noise_dps)
        if self._tables_now is None or self._tables_now.key != key:
            n = IMU_LEVELS
            values = self._in_frame_units(self._side_values(
                np.repeat(np.arange(n)[:, None], IMU_CHANNELS, axis=1))).astype(np.float32)
            names = self._side_fields()
            rec = np.zeros(IMU_CHANNELS * n + 1, dtype=f.dtype)  # the last one: all zero
            for c, name in enumerate(names):
                rec[name][c * n:(c + 1) * n] = values[:, c]
            crc = f.crc.compute_rows(rec.view(np.uint8).reshape(-1, f.size)[:, :f.crc_span])
            temp = self._temperature_terms.get(f.name)
            if temp is None:
                t = np.zeros(65536 + 1, dtype=f.dtype)
                t[f.temperature_field][:65536] = np.arange(65536, dtype=np.uint16
                                                           ).view(np.int16)
                tc = f.crc.compute_rows(t.view(np.uint8).reshape(-1, f.size)[:, :f.crc_span])
                temp = self._temperature_terms[f.name] = tc[:-1] ^ tc[-1]
            self._tables_now = _Tables(
                key, f.fixed_encoder(self._col), names, values.T.copy(),
                (crc[:-1] ^ crc[-1]).reshape(IMU_CHANNELS, n), temp)
        return self._tables_now

    def _encode_rows(self, seq: np.ndarray, value: np.ndarray, levels: np.ndarray,
                     temp_c: np.ndarray) -> np.ndarray:
        """Frames (N, size) uint8 of stand samples: `value` (float32, the frame's units) in
        the measured axis's field, the other channels from their levels (`_side`) through
        the tables of `_tables`: two small gathers a field instead of a CRC of each."""
        t = self._tables()
        rows = t.encoder.encode(seq, value)
        frame = rows.view(self.format.dtype)[:, 0]
        crc = np.zeros(len(seq), dtype=np.uint32)
        for c, name in enumerate(t.fields):
            lv = levels[:, c]
            frame[name] = t.values[c].take(lv)
            crc ^= t.terms[c].take(lv)
        temperature = self._temperature_field(temp_c)
        frame[self.format.temperature_field] = temperature
        crc ^= t.temperature.take(temperature.view(np.uint16))
        crc_field = self.format.crc_field
        frame[crc_field] = frame[crc_field] ^ crc
        return rows

    def _encode_frames(self, seq: np.ndarray, value: np.ndarray, values: np.ndarray,
                       temp_c: np.ndarray) -> np.ndarray:
        """Frames of k > 1 stand samples each (=DR below the stand's rate): `values` are
        the frames' sums or means of `_side_values`, encoded field by field."""
        side = self._in_frame_units(values).astype(np.float32)
        rates = np.empty((len(seq), 3), dtype=np.float32)
        rates[:, self._col] = value
        fields = self._side_fields()
        rates[:, self._cross] = side[:, :2]
        return self.format.encode(seq, rates, temperature=self._temperature_field(temp_c),
                                  extra={name: side[:, c] for c, name in enumerate(fields)
                                         if c >= 2})

    def _decimation(self) -> int:
        return max(int(round(self.rate_hz)) // self.data_rate_hz, 1)

    def _quiet_mask(self, first: int, stop: int, at: np.ndarray | None = None) -> np.ndarray:
        """True for the stand samples `at` (default first .. stop - 1) that fell due in
        Configuration Mode: the unit sent nothing then (ICD 3.3, Table 3-1)."""
        at = np.arange(first, stop) if at is None else at
        quiet = np.zeros(len(at), dtype=bool)
        for lo, hi in self._quiet:
            if (hi is None or hi > first) and lo < stop:
                quiet |= (at >= lo) & (at < (stop if hi is None else hi))
        # sessions that ended before these samples are done with
        self._quiet = [(lo, hi) for lo, hi in self._quiet if hi is None or hi > first]
        return quiet

    def _on_decimated_chunk(self, chunk: AxisChunk, k: int) -> None:
        """=DR below the stand's rate: one frame per k stand samples (frame g covers
        samples g*k .. g*k+k-1): delta angles summed, rates averaged (the other channels
        alike: accelerations and temperature averaged). Faults are by stand sample and act
        at the stand's own rate only (not modelled here); a frame whose last sample fell
        due in Configuration Mode is not sent."""
        n0, n = chunk.n0, len(chunk.t_s)
        value = (chunk.fog_dps / self._dps_per_unit).astype(np.float64)
        levels, temp = self._side(n0, n)
        self._carry.append((np.arange(n0, n0 + n, dtype=np.int64), value,
                            self._side_values(levels), temp))
        idx, val, side, temps = (np.concatenate(c) for c in zip(*self._carry, strict=True))
        first = int(-(-idx[0] // k) * k)      # the first whole frame's first sample
        keep_from = first - int(idx[0])
        whole = (len(idx) - keep_from) // k
        if whole > 0:
            span = slice(keep_from, keep_from + whole * k)
            delta = self.units in ("deg", "rad")
            groups = val[span].reshape(whole, k)
            frame_value = groups.sum(axis=1) if delta else groups.mean(axis=1)
            frame_side = side[span].reshape(whole, k, IMU_CHANNELS).mean(axis=1)
            if delta:                         # angles over the frame: the rates summed
                frame_side[:, :2] *= k
            seq = np.arange(first // k, first // k + whole, dtype=np.int64)
            rows = self._encode_frames(seq, frame_value.astype(np.float32), frame_side,
                                       temps[span].reshape(whole, k).mean(axis=1))
            sent = ~self._quiet_mask(first, first + whole * k, seq * k + k - 1)
            with self._qlock:
                self._queue.append((rows[sent].tobytes(), first + whole * k))
            self.frames_encoded += int(sent.sum())
        rest = keep_from + whole * k
        self._carry = [(idx[rest:], val[rest:], side[rest:], temps[rest:])] \
            if rest < len(idx) else []
        self._next_sample = n0 + n

    def settled(self, t_s: float, final: bool) -> bool:
        if final:
            self._encode_pending()
        return super().settled(t_s, final)

    def _configuration(self, on: bool, now_s: float | None = None) -> None:
        self._encode_pending()   # samples released before the session, as they were
        super()._configuration(on, now_s)

    def _deferrable(self) -> bool:
        """A chunk may wait to be encoded with the next ones: on a stepped clock, while a
        reader has the port and the unit streams plainly (every stand sample a frame, no
        Configuration Mode session to mask, no fault to place), so encoding later, in one
        call, gives the very frames encoding now would."""
        return self._stepped and not self.config_mode and not self._quiet \
            and not self._faults and self._decimation() == 1 and not self._nobody_reads()

    def _encode_pending(self) -> None:
        """Encode and queue the chunks kept back (`_deferrable`), as one."""
        with self.axis.lock:
            if not self._pending:
                return
            parts, self._pending, self._pending_n = self._pending, [], 0
            if len(parts) == 1:
                chunk = parts[0]
            else:
                t_s, rate_cmd, w_true, phi = (np.concatenate(a) for a in zip(
                    *((c.t_s, c.rate_cmd_dps, c.w_true_dps, c.phi_deg) for c in parts),
                    strict=True))
                chunk = AxisChunk(parts[0].n0, t_s, rate_cmd, w_true, phi,
                                  lambda: np.concatenate([c.fog_dps for c in parts]))
            self._encode_chunk(chunk)

    def _on_chunk(self, chunk: AxisChunk) -> None:
        """The axis released stand samples (called under the axis's lock)."""
        if self._deferrable():
            self._pending.append(chunk)
            self._pending_n += len(chunk.t_s)
            if self._pending_n >= DEFER_SAMPLES:
                self._encode_pending()
            return
        self._encode_pending()
        self._encode_chunk(chunk)

    def _encode_chunk(self, chunk: AxisChunk) -> None:
        if self._nobody_reads():
            self._carry = []
            if self._stepped:   # what waited for a reader is gone with these
                with self._qlock:
                    self._queue.clear()
                    self._queued_bytes = 0
            self._next_sample = chunk.n0 + len(chunk.t_s)
            if self.keep_truth:   # truth stays one row a stand sample: these were not sent
                n0, n = chunk.n0, len(chunk.t_s)
                off = np.zeros(n, dtype=bool)
                self._truth.append((np.arange(n0, n0 + n, dtype=np.int64), chunk.fog_dps.copy(),
                                    (chunk.fog_dps / self._dps_per_unit).astype(np.float32),
                                    off, off))
            return
        k = self._decimation()
        if k > 1:
            self._on_decimated_chunk(chunk, k)
            return
        self._carry = []
        n0, n = chunk.n0, len(chunk.t_s)
        idx = np.arange(n0, n0 + n, dtype=np.int64)
        value = (chunk.fog_dps / self._dps_per_unit).astype(np.float32)
        # frames due in Configuration Mode are never sent (ICD 3.3); the counter runs on
        keep = ~self._quiet_mask(n0, n0 + n) if self._quiet else np.ones(n, dtype=bool)
        rows = self._encode_rows(idx, value, *self._side(n0, n)) \
            if keep.any() else np.zeros((n, self.format.size), dtype=np.uint8)
        intact = np.ones(n, dtype=bool)
        cuts: dict[int, list[Hold | tuple[bytes | memoryview, int]]] = {}
        for f in self._faults:
            if isinstance(f, Corrupt | Drop):
                lo, hi = max(f.sample, n0), min(f.sample + f.count, n0 + n)
                if lo < hi:
                    if isinstance(f, Drop):
                        keep[lo - n0:hi - n0] = False
                    else:
                        rows[lo - n0:hi - n0, f.byte] ^= np.uint8(f.xor)
                        intact[lo - n0:hi - n0] = False
            elif isinstance(f, Stall) and f.lose:
                lo = max(f.sample, n0)
                hi = min(f.sample + round(f.duration_s * self.rate_hz), n0 + n)
                if lo < hi:
                    keep[lo - n0:hi - n0] = False
            elif n0 <= f.sample < n0 + n:
                if isinstance(f, Garbage):
                    cuts.setdefault(f.sample, []).append((self._garbage(f), f.sample))
                elif isinstance(f, Stall):
                    cuts.setdefault(f.sample, []).append(
                        Hold(f.sample / self.rate_hz + f.duration_s))
        items: list[tuple[bytes | memoryview, int] | Hold] = []
        at = n0
        whole = bool(keep.all())
        for s in sorted(cuts) + [n0 + n]:
            seg = slice(at - n0, s - n0)
            if s > at:
                # the frames as they are (a view the queue keeps alive), or those not dropped
                out = rows[seg] if whole else rows[seg][keep[seg]]
                items.append((out.reshape(-1).data, s))
            items.extend(cuts.get(s, []))
            at = s
        with self._qlock:
            self._queue.extend(items)
            self._queued_bytes += sum(len(i[0]) for i in items if isinstance(i, tuple))
        self._rouse()
        self._next_sample = n0 + n
        self.frames_encoded += int(keep.sum())
        if self.keep_truth:
            self._truth.append((idx, chunk.fog_dps.copy(), value, keep, intact & keep))

    def _garbage(self, f: Garbage) -> bytes:
        rng = np.random.default_rng(f.seed)
        noise = rng.integers(0, 256, f.nbytes, dtype=np.uint8)
        if f.decoys and f.nbytes >= 8:
            h = np.frombuffer(self.format.header, dtype=np.uint8)
            size = self.format.size
            # header patterns inside the noise, and a frame cut off at its end
            for p in rng.integers(0, max(f.nbytes - len(h), 1), max(f.nbytes // size, 1)):
                noise[p:p + len(h)] = h[:f.nbytes - p]
            tail = max(f.nbytes - size // 2, 0)
            noise[tail:tail + len(h)] = h[:f.nbytes - tail]
        return noise.tobytes()
