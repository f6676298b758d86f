"""The FOG's twin: the simulated stand's FOG output as binary frames on a pseudo-terminal.

The driver opens the pty's slave path with pyserial exactly as it opens /dev/ttyUSB0,
so the test exercises the real byte path: termios, partial reads, the kernel's buffers.
The twin listens to the stand's axis from sample 0 and writes stand sample n as frame n
(sequence n mod 128) when the stand's clock reaches it. It never drops a frame a reader
waits for: writes block while the reader is behind, and the frames go out late, not
never. Frames due while no reader has the port are not sent, as a FOG streams into a
cable nobody listens to (on the co-simulation: no driver counts the channel, see
drivers/clock.py channel_opened; paced: the pty's master sees POLLHUP): the rate ladder
opens an axis's FOG for that axis's units only, and the frames of the hours between
are nobody's (the driver indexes its first frame from the clock, drivers/fog.py).
Faults are injected on purpose, by stand sample, and recorded in the twin's truth.

Configuration (drivers/kvh_config.py, 1775 IMU ICD sections 3.3, 7 and 8): the twin
answers `=CONFIG,1|0`, `=OUTPUTFMT,`, `=ROTFMT,`, `=ROTUNITS,`, `=DR,` and their `?`
queries as the ICD's conventions say (a command echoes without '=', a query answers
`NAME,value`, an unknown word in Configuration Mode `INVALID,...`; in Normal Mode input
is ignored), and `?IS` with its serial (`IS,<serial>`, ICD 8.20). In Configuration Mode
it sends no frame, and on leaving it resumes at its rate: the frames that fell due
meanwhile are never sent (no backlog), so the sequence counter jumps by the session's
length (ICD 3.3, Table 3-1). Its rotational fields start at the KVH power-on default,
delta radians (Table 5-10), unless built with `units` (a FOG configured earlier, kept in
its non-volatile memory). `=DR` sets the frame rate: a rate that divides the stand's sample
rate sends one frame per that many samples (delta angles summed, rates averaged, the
sequence counting frames); a faster one, or one that does not divide it, is refused with
INVALID (a twin limit: the stand samples no faster). It also answers `=BAUD`, `=LINFMT`,
`=LINUNITS`, `=TEMPUNITS`, `=FILTEN,<A|G>,<0|1>`, `=RSTCFG` and their queries (the 1775
ICD section 8; drivers/kvh_config.py says which spellings are unverified). The
other channels are the stand's too (AxisModel.imu_levels, a random stream of their own):
the cross-axis gyros read white noise at the FOG's noise level, the accelerometers +1 g
along the table axis (vertical; the ICD's polarity: +1 g with the positive axis up) and 0 g
across it with a little noise, and the temperature warms slowly from the ambient with a
small noise, sent in whole degrees (FogTwin._side).

Time. On the co-simulation clock (sims/clock.py SteppedClock) the twin is a participant:
the clock's steps release the stand's samples (`advance`), the frames go out on the pty,
and the clock counts the bytes through the channel named by the pty's path: a step ends
only when the driver has consumed what the twin wrote (`settled`). On a paced clock the
twin's thread follows the clock itself and paces it (`delivered_s`).

Two details of real ports matter here. pyserial flushes the input queue when it opens
the port, so the twin writes nothing until a reader has the slave open and the stand
clock runs (the engine starts the clock after opening every instrument). And the
twin closes its own slave descriptor, so that "a reader has it open" is visible on the
master as the absence of POLLHUP.
"""

from __future__ import annotations

import errno
import math
import os
import select
import threading
import time
import tty
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from drivers.fog import dps_per_unit, first_sample_after
from drivers.fog_formats import AXES, FixedFieldsEncoder, get_format
from drivers.kvh_config import (
    BAUD_RATES,
    DATA_RATES_HZ,
    FEET_PER_METER,
    G0_MPS2,
    LIN_FORMATS,
    LIN_UNITS,
    POWER_ON_UNITS,
    TEMP_UNITS,
    UNIT_WORDS,
    WORDS,
    units_of,
)
from sims.clock import SteppedClock
from sims.stand import (
    IMU_CHANNELS,
    IMU_LEVEL_MEAN,
    IMU_LEVEL_STD,
    IMU_LEVELS,
    TEMPERATURE_HOLD_SAMPLES,
    AxisChunk,
    SimulatedStand,
)

_TICK_S = 0.002            # real seconds between looks at the clock when idle
_OPEN_SETTLE_S = 0.05      # real seconds for pyserial to configure and flush after open
_WRITE_POLL_MS = 50
#: on a stepped clock, bytes the channel may hold between the steps of one wait (queued
#: in the twin, in the pty, not yet decoded): the twin encodes while the driver decodes
_LEAD_BYTES = 4 << 20
#: what `?IS` answers when the twin is given no serial (ICD 8.20: "a text string,
#: typically with a numeric value")
DEFAULT_SERIAL = "0"
#: the accelerometers' noise, g rms a sample. An assumption of the twin: the stand file
#: says nothing of the accelerometers and the ICD pages we read give no figure
ACCEL_NOISE_G = 5e-4
#: the temperature sensor (deg C): the unit warms from the ambient by WARM_UP_C with the
#: time constant WARM_UP_TAU_S from power-on (stand time 0), read with this noise. The
#: frame carries whole degrees (ICD Table 5-2), so a short record reads the ambient
WARM_UP_C = 1.0
WARM_UP_TAU_S = 1200.0
TEMPERATURE_NOISE_C = 0.05


@dataclass(frozen=True)
class Corrupt:
    """Frames sample .. sample+count-1 go out with one byte xor-ed (their CRC fails)."""

    sample: int
    count: int = 1
    byte: int = 14          # offset in the frame; 0..3 breaks the header instead
    xor: int = 0x5A


@dataclass(frozen=True)
class Drop:
    """Frames sample .. sample+count-1 are never sent (the counter still advances)."""

    sample: int
    count: int = 1


@dataclass(frozen=True)
class Garbage:
    """nbytes of noise go out just before frame `sample` (no frame is lost).

    With `decoys`, the noise carries header patterns and a cut-off frame, the worst
    case for resynchronisation.
    """

    sample: int
    nbytes: int
    seed: int = 0
    decoys: bool = True


@dataclass(frozen=True)
class Stall:
    """The output stops at frame `sample` for duration_s (stand seconds).

    lose=False: the frames are held and go out late (a blocked link).
    lose=True: the frames of that time are never sent (the unit stopped transmitting
    while its counter ran).
    """

    sample: int
    duration_s: float
    lose: bool = False


Fault = Corrupt | Drop | Garbage | Stall


@dataclass(frozen=True)
class TwinTruth:
    """What the twin did for samples i_from .. i_to - 1."""

    index: np.ndarray
    fog_dps: np.ndarray     # the stand's FOG output, float64
    value: np.ndarray       # the float32 put in the frame (in the frame's units)
    rate_dps: np.ndarray    # value converted back to deg/s as a driver must
    sent: np.ndarray        # the frame went out (not dropped, not lost to a stall)
    intact: np.ndarray      # ... and was not corrupted


@dataclass(frozen=True)
class _Hold:
    until_s: float


@dataclass(frozen=True)
class _Tables:
    """FogTwin._tables: what encoding a frame needs for one set of the unit's settings."""

    key: tuple[object, ...]
    encoder: FixedFieldsEncoder    # the measured field and the counter; the rest 0
    fields: list[str]              # the other channels' fields (FogTwin._side_fields)
    values: np.ndarray             # (IMU_CHANNELS, IMU_LEVELS) float32, frame units
    terms: np.ndarray              # (IMU_CHANNELS, IMU_LEVELS) uint32: their CRC terms
    temperature: np.ndarray        # (65536,) uint32: the temperature field's, by its bits


class FogTwin:
    """Frames of one stand axis's FOG on a pty. Create it before the stand clock starts."""

    def __init__(self, stand: SimulatedStand, axis: str, *, fmt: str = "kvh-a",
                 axis_letter: str = "z", units: str = POWER_ON_UNITS, temperature: float = 25.0,
                 keep_truth: bool = False, serial: str = DEFAULT_SERIAL) -> None:
        self.format = get_format(fmt)
        if axis_letter not in AXES:
            raise ValueError(f"FOG twin axis letter {axis_letter!r} not one of x, y, z")
        if not serial or not serial.isascii() or not serial.isprintable():
            raise ValueError(f"FOG twin serial {serial!r}: printable ASCII (the text of "
                             "its ?IS answer line, ICD 8.20)")
        #: the unit's serial number, answered to ?IS (ICD 56-0298 Rev. B 8.20, p. 44)
        self.serial = serial
        self.stand = stand
        self.axis = stand.axis(axis)
        self.clock = stand.clock
        self.rate_hz = self.axis.rate_hz
        self.units = units
        self._col = AXES.index(axis_letter)
        #: the frame's other two rotational (and linear) fields: the cross axes
        self._cross = [k for k in range(3) if k != self._col]
        self._dps_per_unit = dps_per_unit(units, self.rate_hz)
        self.config_mode = False
        self.data_rate_hz = int(round(self.rate_hz))
        self.frame_letter = self.format.name.rsplit("-", 1)[-1].upper()
        self.baud = 921600
        self.lin_format, self.lin_units, self.temp_units = "ACCEL", "METERS", "C"
        self.filter_enabled = {"A": True, "G": True}
        # samples of a partial frame (=DR below the stand's rate): index, value, and the
        # other channels (cross-axis rates, accelerations, temperature; _side)
        self._carry: list[tuple[np.ndarray, ...]] = []
        #: stand samples [start, end) while in Configuration Mode: never sent (end None:
        #: still in it)
        self._quiet: list[tuple[int, int | None]] = []
        self._tables_now: _Tables | None = None
        self._temperature_terms: dict[str, np.ndarray] = {}
        self._inbuf = bytearray()
        self.commands: list[str] = []  # every line received (tests)
        #: the ambient the unit's temperature starts from, deg C (it warms up: _side)
        self.temperature = float(temperature)
        self.keep_truth = keep_truth
        self._faults: list[Fault] = []
        self._queue: deque[tuple[bytes | memoryview, int] | _Hold] = deque()
        self._sent_n = 0          # frames up to this stand sample are out on the port
        self._reading = False     # a reader has the port open
        self._slow: tuple[float, float, int] | None = None  # (frames/real s, since, sent)
        self._qlock = threading.Lock()
        self._next_sample = 0
        self._truth: list[tuple[np.ndarray, ...]] = []
        self._master: int | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._wake = threading.Event()   # frames queued: the writer need not wait a tick
        self._gate_open = False          # a reader settled on the port, the clock runs
        self._queued_bytes = 0
        self._stepped = bool(getattr(self.clock, "stepped", False))
        self._leave: Callable[[], None] | None = None
        self._presence: select.poll | None = None  # the master, polled for a reader
        self.path: str | None = None
        self.bytes_written = 0
        self.frames_encoded = 0
        with self.axis.lock:
            if self.axis.samples_generated:
                raise RuntimeError(
                    f"FOG twin for axis {axis!r} created after the stand generated "
                    f"{self.axis.samples_generated} samples: create it before anything "
                    f"advances the axis (the clock, command_rate), so frame n is stand "
                    f"sample n")
            self.axis.listeners.append(self._on_chunk)

    # -- faults --------------------------------------------------------------------------------
    @property
    def next_sample(self) -> int:
        """The first stand sample not yet encoded: a fault must lie at or after it."""
        with self.axis.lock:
            return self._next_sample

    def inject(self, *faults: Fault) -> None:
        """Schedule faults by stand sample; each must lie ahead of what is already encoded."""
        with self.axis.lock:
            for f in faults:
                if f.sample < self._next_sample:
                    raise ValueError(f"{f} is in the past: samples up to "
                                     f"{self._next_sample - 1} are already encoded")
                self._faults.append(f)

    # -- encoding (runs in whichever thread advances the axis) -------------------------------
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

    def _nobody_reads(self) -> bool:
        """No reader has the port: the chunk's frames would go nowhere (module docstring)."""
        if self._stop.is_set():
            return False
        if self._stepped:   # set by the driver between clock steps: the same on every run
            return self.path is None or not self._stepped_clock.has_consumer(self.path)
        return self._presence is not None and not self._reader_present(self._presence)

    def _on_chunk(self, chunk: AxisChunk) -> None:
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
        cuts: dict[int, list[_Hold | tuple[bytes | memoryview, int]]] = {}
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
                        _Hold(f.sample / self.rate_hz + f.duration_s))
        items: list[tuple[bytes | memoryview, int] | _Hold] = []
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
        self._wake.set()
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

    def slow_down(self, frames_per_real_s: float | None) -> None:
        """From now on send at most this many frames a real second (None: no limit).

        A twin slowed on purpose stands for a loaded machine or a slow link: the paced
        clock must follow it (sims/clock.py), never leave the FOG's reader waiting.
        """
        if frames_per_real_s is not None and not frames_per_real_s > 0:
            raise ValueError(f"frames_per_real_s must be > 0, got {frames_per_real_s}")
        self._slow = (None if frames_per_real_s is None
                      else (float(frames_per_real_s), time.monotonic(), self._sent_n))

    def _throttle(self) -> None:
        slow = self._slow
        if slow is not None:
            rate, since, sent0 = slow
            time.sleep(max(since + (self._sent_n - sent0) / rate - time.monotonic(), 0.0))

    # -- the port ----------------------------------------------------------------------------
    def start(self) -> str:
        """Open the pty and start writing; returns the slave path for the driver."""
        if self._thread is not None:
            raise RuntimeError("FOG twin already started")
        master, slave = os.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        os.close(slave)  # a reader opening the path is then seen as POLLHUP clearing
        os.set_blocking(master, False)
        self._master = master
        self._presence = select.poll()
        self._presence.register(master, select.POLLOUT)
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=f"fog-twin-{self.axis.name}",
                                        daemon=True)
        self._thread.start()
        if self._stepped:
            self._leave = self._stepped_clock.join(self)
        return self.path

    # -- the co-simulation (sims/clock.py SteppedClock) -------------------------------------
    @property
    def _stepped_clock(self) -> SteppedClock:
        """The co-simulation's clock: reached only on a stepped stand (self._stepped)."""
        assert isinstance(self.clock, SteppedClock)
        return self.clock

    def next_event_s(self, t_s: float) -> float:
        return math.inf  # frames follow the stand's samples; a hold ends with the clock

    def advance(self, t_s: float) -> None:
        self.axis.advance_to(t_s)

    def settled(self, t_s: float, final: bool) -> bool:
        """Frames up to t_s out and decoded (final), or within the lead of it."""
        if self._stop.is_set() or self.path is None \
                or not self._stepped_clock.has_consumer(self.path) or self.config_mode:
            return True
        if not self._gate_open:
            return False
        with self._qlock:
            head = self._queue[0] if self._queue else None
            queued = self._queued_bytes
        due = head is not None and (not isinstance(head, _Hold) or head.until_s <= t_s)
        backlog = self._stepped_clock.backlog(self.path)
        if final:
            return not due and backlog == 0
        return queued + backlog <= _LEAD_BYTES

    def delivered_s(self) -> float:
        """The clock's pacer: stand time up to which frames are out on the port.

        A twin nobody reads (no reader yet, or the reader gone) paces nothing (inf), and a
        stall injected on purpose holds the frames, not the clock.
        """
        if not self._reading or self._stop.is_set() or self.config_mode:
            return math.inf   # (Configuration Mode: the unit sends nothing to keep up with)
        with self._qlock:
            head = self._queue[0] if self._queue else None
        sent_s = (self._sent_n - 1) / self.rate_hz
        return max(head.until_s, sent_s) if isinstance(head, _Hold) else sent_s

    def stop(self) -> None:
        self._stop.set()
        self._wake.set()
        if self._leave is not None:
            self._leave()
            self._leave = None
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        if self._master is not None:
            os.close(self._master)
            self._master = None
        with self.axis.lock:
            if self._on_chunk in self.axis.listeners:
                self.axis.listeners.remove(self._on_chunk)

    def __enter__(self) -> FogTwin:
        if self._thread is None:
            self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _reader_present(self, poller: select.poll) -> bool:
        return not any(ev & select.POLLHUP for _, ev in poller.poll(0))

    def _run(self) -> None:
        assert self._master is not None and self.path is not None  # set by start()
        poller = select.poll()
        poller.register(self._master, select.POLLOUT)
        seen: float | None = None
        while not self._stop.is_set():  # the gate: a reader settled, and a running clock
            self._serve_commands()
            if seen is None and self._reader_present(poller):
                seen = time.monotonic()
                self._reading = True
            if self._stepped:
                # the driver says when it records (after its configuration dialogue and
                # the flush that ends it): frames written before would be flushed, and
                # the first frame read would not be stand sample 0
                if seen is not None and self._stepped_clock.has_consumer(self.path):
                    break
            elif seen is not None and time.monotonic() - seen >= _OPEN_SETTLE_S \
                    and getattr(self.clock, "running", True):
                break
            time.sleep(_TICK_S)
        self._gate_open = True
        if self._stepped:
            self._stepped_clock.poke()
        while not self._stop.is_set():
            self._serve_commands(None if self._stepped else poller)
            if self.config_mode:  # no binary output in Configuration Mode (ICD 3.3)
                time.sleep(_TICK_S)
                continue
            if not self._stepped:  # a paced clock: the twin follows it (stepped: advance())
                self.axis.advance_to(self.clock.now())
            if not self._drain(poller):
                self._wake.wait(_TICK_S)
                self._wake.clear()

    # -- configuration (ICD section 7) -------------------------------------------------------
    def _serve_commands(self, poller: select.poll | None = None) -> None:
        """Answer the lines received. With `poller` (the stream running on a paced clock)
        the frames due up to `=CONFIG,1` go out before its answer: the unit streamed
        until then (on a stepped clock the clock's steps release the samples)."""
        assert self._master is not None
        try:
            data = os.read(self._master, 4096)
        except (BlockingIOError, OSError):
            return
        self._inbuf.extend(data)
        while True:
            cut = [i for i in (self._inbuf.find(b"\r"), self._inbuf.find(b"\n")) if i >= 0]
            if not cut:
                return
            i = min(cut)
            line = bytes(self._inbuf[:i]).decode("ascii", "replace").strip()
            del self._inbuf[:i + 1]
            if line:
                self.commands.append(line)
                now_s = None
                if poller is not None and not self.config_mode \
                        and line.upper().replace(" ", "") == f"={WORDS.config},1":
                    now_s = self.clock.now()
                    self.axis.advance_to(now_s)
                    self._drain(poller)
                reply = self._answer(line, now_s)
                if reply is not None:  # after the frames already queued in the port
                    self._write_reply((reply + "\r\n").encode("ascii"))

    def _write_reply(self, data: bytes) -> None:
        """Write a reply whole, waiting while the port's buffer is full (a reader still
        busy with the frames sent before Configuration Mode)."""
        assert self._master is not None
        view = memoryview(data)
        deadline = time.monotonic() + 5.0
        while view and not self._stop.is_set() and time.monotonic() < deadline:
            try:
                view = view[os.write(self._master, view):]
            except BlockingIOError:
                select.select([], [self._master], [], _WRITE_POLL_MS / 1000)
            except OSError:
                return  # no reader: the reply is lost, as on a cable nobody listens to

    def _answer(self, line: str, now_s: float | None = None) -> str | None:
        w = WORDS
        body = line[1:].upper()
        name, _, arg = body.partition(",")
        if line.startswith("=") and name == w.config and arg in ("0", "1"):
            self._configuration(arg == "1", now_s)
            return body
        if not self.config_mode:
            return None  # Normal Mode ignores input (ICD section 7)
        fmt, units = UNIT_WORDS[self.units]
        values = {w.output_format: self.frame_letter, w.rot_format: fmt, w.rot_units: units,
                  w.data_rate: str(self.data_rate_hz), w.baud: str(self.baud),
                  w.lin_format: self.lin_format, w.lin_units: self.lin_units,
                  w.temp_units: self.temp_units}
        if line.startswith("?") and name in values and not arg:
            return f"{name},{values[name]}"
        if line.startswith("?") and name == w.serial_number and not arg:
            return f"{name},{self.serial}"   # ICD 8.20 (p. 44): "IS,[Serial Number]"
        if line.startswith("?") and name == w.filter_enable and arg in ("A", "G"):
            return f"{name},{arg},{int(self.filter_enabled[arg])}"
        if line.startswith("=") and self._setting(name, arg, fmt, units):
            return body
        return "INVALID," + line

    def _configuration(self, on: bool, now_s: float | None = None) -> None:
        """=CONFIG,1|0. In Configuration Mode "the unit will stop output of binary data"
        and it resumes at its configured rate on leaving (ICD 56-0298 Rev. B 3.3, Table
        3-1): the frames that fell due meanwhile are not sent then, as no backlog, and the
        sequence counter of the first frame after it follows the time (stand sample n is
        frame n: a gap of the session's length, as drivers/fog.py and `bench decode`
        count one). The bench's driver configures before it records (drivers/fog.py
        Fog.open), on a clock not started yet: no sample falls due in that session."""
        t_s = self.clock.now() if now_s is None else now_s  # (before the axis's lock)
        at = first_sample_after(t_s, self.rate_hz)
        with self.axis.lock:
            if on and not self.config_mode:
                self._quiet.append((at, None))
            elif not on and self.config_mode and self._quiet:
                start, _ = self._quiet[-1]
                self._quiet[-1] = (start, max(at, start))
            self.config_mode = on

    def _setting(self, name: str, arg: str, fmt: str, units: str) -> bool:
        """Apply one `=NAME,arg` (Configuration Mode); False: the unit refuses it."""
        w = WORDS
        if name == w.rot_format and arg in ("DELTA", "RATE"):
            self._set_units(units_of(arg, units))
        elif name == w.rot_units and arg in ("DEG", "RAD"):
            self._set_units(units_of(fmt, arg))
        elif name == w.output_format and arg in ("A", "B"):
            self._set_output_format(arg)
        elif name == w.data_rate and arg.isdigit() and int(arg) in DATA_RATES_HZ:
            if int(round(self.rate_hz)) % int(arg):
                return False  # twin limit: the stand samples at rate_hz, no faster
            with self.axis.lock:
                self.data_rate_hz = int(arg)
        elif name == w.baud and arg.isdigit() and int(arg) in BAUD_RATES:
            self.baud = int(arg)
        elif name == w.lin_format and arg in LIN_FORMATS:
            self.lin_format = arg
        elif name == w.lin_units and arg in LIN_UNITS:
            self.lin_units = arg
        elif name == w.temp_units and arg in TEMP_UNITS:
            self.temp_units = arg
        elif name == w.filter_enable and arg[:2] in ("A,", "G,") and arg[2:] in ("0", "1"):
            self.filter_enabled[arg[0]] = arg[2:] == "1"
        elif name == w.reset_config and not arg:
            self._factory_config()  # the baud rate stays (ICD, RSTCFG note)
        else:
            return False
        return True

    def _factory_config(self) -> None:
        with self.axis.lock:
            self.data_rate_hz = int(round(self.rate_hz))
            self.units = POWER_ON_UNITS
            self._dps_per_unit = dps_per_unit(self.units, self.rate_hz)
        self._set_output_format("A")
        self.lin_format, self.lin_units, self.temp_units = "ACCEL", "METERS", "C"
        self.filter_enabled = {"A": True, "G": True}

    def _set_output_format(self, letter: str) -> None:
        with self.axis.lock:
            self.format = get_format(f"kvh-{letter.lower()}")
            self.frame_letter = letter

    def _set_units(self, units: str) -> None:
        with self.axis.lock:
            self.units = units
            self._dps_per_unit = dps_per_unit(units, self.rate_hz)

    def _drain(self, poller: select.poll) -> bool:
        """Write what is due; False if there was nothing to write."""
        wrote = False
        while not self._stop.is_set():
            # the clock's time is read before the queue's lock is taken: the paced clock
            # calls delivered_s (which takes that lock) while it holds its own
            now_s = self.clock.now()
            with self._qlock:
                if not self._queue:
                    return wrote
                item = self._queue.popleft()
                if isinstance(item, _Hold):
                    if now_s < item.until_s:
                        self._queue.appendleft(item)
                        return wrote
                    continue
                self._queued_bytes -= len(item[0])
                if self._stepped and self.path is not None:
                    self._stepped_clock.sent(self.path, len(item[0]))  # counted before it can be read
            data, n_end = item
            self._write_all(data, poller)
            self._sent_n = max(self._sent_n, n_end)
            self._throttle()
            wrote = True
        return wrote

    def _write_all(self, data: bytes | memoryview, poller: select.poll) -> None:
        view = memoryview(data)
        while view and not self._stop.is_set():
            try:
                k = os.write(self._master, view)  # type: ignore[arg-type]
                self._reading = True
                view = view[k:]
                self.bytes_written += k
            except BlockingIOError:
                events = poller.poll(_WRITE_POLL_MS)
                gone = any(ev & select.POLLHUP for _, ev in events)
                self._reading = not gone  # a reader gone paces nothing
                if gone:
                    time.sleep(_WRITE_POLL_MS / 1000)  # reader gone: keep the frames
            except OSError as e:
                if e.errno != errno.EIO:
                    raise
                time.sleep(_WRITE_POLL_MS / 1000)

    # -- truth -------------------------------------------------------------------------------
    def truth(self, i_from: int = 0, i_to: int | None = None) -> TwinTruth:
        """What the twin encoded for samples i_from .. i_to - 1 (all so far by default)."""
        if not self.keep_truth:
            raise RuntimeError("this FOG twin keeps no truth (keep_truth=False)")
        with self.axis.lock:
            parts = list(self._truth)
        if not parts:
            e = np.empty(0)
            return TwinTruth(e.astype(np.int64), e, e.astype(np.float32), e,
                             e.astype(bool), e.astype(bool))
        idx, fog, value, sent, intact = (np.concatenate(p) for p in zip(*parts, strict=True))
        hi = len(idx) if i_to is None else i_to
        s = slice(i_from, hi)
        return TwinTruth(idx[s], fog[s], value[s],
                         value[s].astype(np.float64) * self._dps_per_unit, sent[s], intact[s])
