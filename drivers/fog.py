"""A fibre-optic gyro streaming binary frames over a serial port.

The FOG is the only instrument that sees inside a turn (docs/method.md A3-A5), and a lost
or misread frame is a wrong instability figure, so this driver is built around one
rule: the bytes are the record. A background thread reads the port for as long as it
is open, appends every byte as received to the raw capture file (flushed after every
read), and decodes with the same `StreamDecoder` that `bench decode` runs on the file
afterwards, so the capture re-decodes to exactly the samples the engine used.

Sample index: index n is the sample at t = n / rate_hz on the stand's time axis. A FOG
streams from power-on whether or not a host reads it, so the first frame received is
placed by the clock: opened with the clock at t, the capture starts at the first
sample after t (`first_index`, `first_sample_after`), and the first frame takes the index nearest it that
its sequence counter allows (exact while the frame came within half a counter wrap of
t: 64 ms at 1 kHz for KVH). Each later frame's index follows from the sequence counter,
so lost frames keep their place (as invalid samples). On the simulated stand the twin
emits stand sample n as frame n, and sends nothing while no reader has the port, so
the first frame after opening at t is the first stand sample after t, indexed exactly
(the rate ladder opens an axis's FOG for that axis's units only). On a real bench the
FOG's time axis and the counter's timebase must still be tied (drivers/time_tie.py).

A loss of a whole multiple of the sequence modulus (128 frames for KVH) leaves no mark
in the bytes. The reader therefore also watches the clock: when the data resume after
a silence, the frames decoded must account for the silence; if the sample clock runs
behind the stand clock by half a counter wrap or more for a sustained time, the driver
flags the indices after that point as uncertain (health "error").
"""

from __future__ import annotations

import errno
import hashlib
import math
import os
import select
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, TYPE_CHECKING, TypedDict

import numpy as np
import serial

from drivers.clock import (
    Clock,
    channel_closed,
    channel_opened,
    consumed,
    in_flight,
    real_budget_s,
    settle_channel,
    stepped,
)
from drivers.fog_formats import (
    AXES,
    FORMATS,
    DecodeState,
    DecodeStats,
    FrameFormat,
    Frames,
    StreamDecoder,
    decode,
    get_format,
)
from drivers.kvh_config import MODES, KvhConfigError, KvhConfigurator, KvhTarget
from drivers.port_pump import PortPump
from drivers.waits import MAX_LATE_REAL_S, MIN_REAL_MARGIN_S, wait_on_clock

if TYPE_CHECKING:
    from hashlib import _Hash  # typeshed's name for a hash object

    from drivers.fog_settings import FogSettings

__all__ = ["FORMATS", "CaptureCursor", "DecodeState", "DecodeStats", "Fog", "FogError",
           "FogSamples", "FogStats", "FogTimeout", "Frames", "StreamDecoder", "decode", "dps_per_unit",
           "read_capture"]

# units a FOG's rotational data can carry; "deg" and "rad" are delta angles per sample
RATE_UNITS = ("deg/s", "rad/s", "deg", "rad")

_READ_TIMEOUT_S = 0.05     # real seconds a read waits for the first byte
#: decode in batches of up to this many bytes. Only a stream faster than _BATCH_REAL_S
#: lets through fills one (a co-simulated stand: a step's frames in one burst); there
#: 512 kB took the paper ladder from 117 to 104-110 s wall against 128 kB (fewer raw-file
#: writes, CRC calls and clock wake-ups per frame; 1 MB no better)
_BATCH_BYTES = 1 << 19
#: a raw capture is decoded offline in pieces of this many bytes (the decoder's fastest:
#: larger pieces spill the CPU's caches)
_CAPTURE_CHUNK_BYTES = 1 << 18
_BATCH_GAP_S = 0.001       # real seconds a batch waits for the next piece of a fast stream
_BATCH_REAL_S = 0.005      # ... and at most this long in all (a slow stream's latency)
_STEPPED_GAP_S = 0.0002    # on a stepped clock: a step's frames come in one burst
#: on a stepped clock a batch goes on while the twin has sent bytes it does not hold yet,
#: looking every _IN_FLIGHT_POLL_S, for at most this many real seconds past _BATCH_REAL_S
#: (a twin that counted bytes it never wrote cannot hold the reader longer)
_IN_FLIGHT_REAL_S = 0.1
_IN_FLIGHT_POLL_S = 0.005
_STALL_FRAMES = 64         # a silence this many frame periods long is a stall,
_STALL_REAL_S = 0.1        # ... and at least this many real seconds (OS, USB latency)
_ALIAS_MIN_REAL_S = 0.02   # the wrap check needs half a wrap to last this long in real time
_LATE_STEP_S = 0.05        # stepped clock: clock s between looks for samples overdue
_ALIAS_WINDOW_S = 0.5      # real seconds over which the lag after a silence is watched


def first_sample_after(t_s: float, rate_hz: float) -> int:
    """The index of the first sample after clock time t_s: a FOG opened then sees that
    one first (the simulated stand has released every sample at or before t_s, its
    `advance_to`), or sample 0 on a clock not started yet (t_s = 0)."""
    return 0 if t_s <= 0 else math.floor(t_s * rate_hz + 1e-9) + 1


def dps_per_unit(units: str, rate_hz: float) -> float:
    """deg/s per unit of the frame's rotational data (the twin uses the inverse)."""
    if units == "deg/s":
        return 1.0
    if units == "rad/s":
        return 180.0 / math.pi
    if units == "deg":
        return float(rate_hz)
    if units == "rad":
        return float(rate_hz) * 180.0 / math.pi
    raise ValueError(f"FOG units {units!r} unknown (one of {', '.join(RATE_UNITS)})")


def _nonblocking_fd(ser: serial.Serial) -> int | None:
    """The port's descriptor when it is open non-blocking (pyserial's POSIX ports are),
    so that pieces can be read until it is empty without a size query each; else None."""
    fileno = getattr(ser, "fileno", None)
    if fileno is None:
        return None
    try:
        fd = int(fileno())
        return None if os.get_blocking(fd) else fd
    except (OSError, ValueError, TypeError, serial.SerialException):
        return None


def _gather(fd: int, view: memoryview, size: int, gap_s: float,
            coming: Callable[[], int] | None) -> int:
    """Read from non-blocking `fd` into `view` after its first `size` bytes, as
    `Fog._batch` says; returns the bytes `view` holds."""
    t_end = time.monotonic() + _BATCH_REAL_S
    cap = len(view)
    while size < cap:
        try:
            got = os.readv(fd, (view[size:],))
        except BlockingIOError:
            got = None
        if got:
            size += got
            continue
        # nothing to read now (EAGAIN: None; a tty that returns at once: 0 bytes)
        if coming is not None and coming() > size \
                and time.monotonic() < t_end + _IN_FLIGHT_REAL_S:
            select.select([fd], [], [], _IN_FLIGHT_POLL_S)  # the burst is on its way
            continue
        if got == 0:  # a port that reports data but gives none: pyserial's read says why
            break
        if time.monotonic() >= t_end or not gap_s or \
                not select.select([fd], [], [], gap_s)[0]:
            break
    return size


def _pumped(pump: PortPump, buf: bytearray, gap_s: float,
            coming: Callable[[], int] | None) -> memoryview | None:
    """A batch from the port's pump (drivers/port_pump.py), as `Fog._batch` gathers one
    from the port; None when nothing came within _READ_TIMEOUT_S."""
    fd = pump.fd
    assert fd is not None   # closed only after the reader's loop
    if not select.select([fd], [], [], _READ_TIMEOUT_S)[0]:
        return None
    view = memoryview(buf)
    size = _gather(fd, view, 0, gap_s, coming)
    if size == 0:   # readable and empty: the pipe's end, the pump gone
        raise OSError(errno.EIO, f"{pump.what} ended")
    return view[:size]


class FogCheckpoint(TypedDict):
    """Where a FOG's decoder stood in its raw capture (`Fog.checkpoint`), as the journal
    keeps it; a CaptureCursor continues from it."""

    offset: int
    last_index: int
    last_sequence: int | None
    last_end: int
    first_index: int | None


def _decode_state(mark: FogCheckpoint) -> DecodeState:
    """A checkpoint (`Fog.checkpoint`) as the journal gives it back (its event decoded,
    so each number checked, by bench/core/events.py)."""
    return DecodeState(mark["offset"], mark["last_index"], mark.get("last_sequence"),
                       mark["last_end"], mark.get("first_index"))


class FogError(RuntimeError):
    """The FOG stream failed: the port, the reader or the index can no longer be trusted."""


class FogTimeout(FogError, TimeoutError):
    """An awaited sample did not arrive in time."""


@dataclass(frozen=True)
class FogSamples:
    """Samples i_from .. i_to - 1 of the configured axis; lost samples keep their rows."""

    index: np.ndarray        # int64
    t_s: np.ndarray          # index / rate_hz, on the stand's time axis
    rate_dps: np.ndarray     # float64; NaN where the frame was lost
    valid: np.ndarray        # received, CRC good and the axis's status bit set
    received: np.ndarray     # a frame with this index arrived intact
    temperature: np.ndarray  # float64, as the frame carries it; NaN where lost


@dataclass(frozen=True)
class GapEvent:
    index: int       # first lost sample
    count: int       # samples lost
    t_s: float


@dataclass(frozen=True)
class CrcEvent:
    index: int       # the sample the broken frame would have been, at least
    t_s: float
    offset: int      # byte offset of its header in the raw capture


@dataclass(frozen=True)
class StallEvent:
    t_from_s: float  # stand clock when the silence began
    duration_s: float
    after_index: int  # last index received before it


@dataclass(frozen=True)
class FogStats:
    frames: int
    crc_errors: int
    gaps: int
    lost_frames: int
    skipped_bytes: int
    bytes: int
    crc_events: tuple[CrcEvent, ...]
    gap_events: tuple[GapEvent, ...]
    stalls: tuple[StallEvent, ...]
    lag_s: float            # how far the newest sample trails the clock (latency)
    index_uncertain_from: int | None  # set when frames were lost in whole counter wraps


class _SampleStore:
    """Per-index arrays from `base` on, grown by doubling; bounded by discard_before."""

    def __init__(self) -> None:
        self.base = 0
        self.n = 0  # samples known (received or known lost): indices base .. base+n-1
        cap = 4096
        self.rate = np.empty(cap)
        self.status_ok = np.empty(cap, dtype=bool)
        self.received = np.empty(cap, dtype=bool)
        self.temp = np.empty(cap)

    @property
    def end(self) -> int:
        return self.base + self.n

    def _reserve(self, extra: int) -> None:
        need = self.n + extra
        if need <= self.rate.size:
            return
        cap = max(need, 2 * self.rate.size)
        for name in ("rate", "status_ok", "received", "temp"):
            old = getattr(self, name)
            new = np.empty(cap, dtype=old.dtype)
            new[:self.n] = old[:self.n]
            setattr(self, name, new)

    def append(self, index: np.ndarray, rate: np.ndarray, status_ok: np.ndarray,
               temp: np.ndarray) -> None:
        if index.size and index[0] < self.base:
            # a capture's first frames, from before its first_index (a host clock a
            # little behind the FOG's): not part of the record the clock placed
            keep = index >= self.base
            index, rate, status_ok, temp = index[keep], rate[keep], status_ok[keep], temp[keep]
        if index.size == 0:
            return
        new_end = int(index[-1]) + 1
        m = new_end - self.end
        self._reserve(m)
        s = slice(self.n, self.n + m)
        at: slice | np.ndarray = s  # no frame lost: the frames are the new rows, in order
        if m != index.size:  # (indices increase) else lost frames keep rows, as invalid
            self.rate[s] = np.nan
            self.status_ok[s] = False
            self.received[s] = False
            self.temp[s] = np.nan
            at = index - self.base
        self.rate[at] = rate
        self.status_ok[at] = status_ok
        self.received[at] = True
        self.temp[at] = temp
        self.n += m

    def add(self, frames: Frames, col: int, scale: float, valid_mask: int) -> None:
        """The one conversion from frames to samples, live and from a capture alike."""
        self.append(frames.index, frames.rates[:, col].astype(np.float64) * scale,
                    (frames.status & valid_mask) != 0, frames.temperature.astype(np.float64))

    def samples(self, i_from: int, i_to: int, rate_hz: float) -> FogSamples:
        if i_from < self.base:
            raise ValueError(f"FOG samples before {self.base} were discarded "
                             f"(asked from {i_from})")
        if i_to > self.end:
            raise ValueError(f"FOG samples up to {i_to} asked, only {self.end} known "
                             f"(wait_for_index first)")
        if i_to < i_from:
            raise ValueError(f"empty FOG sample range {i_from} .. {i_to}")
        s = slice(i_from - self.base, i_to - self.base)
        rec = self.received[s].copy()
        index = np.arange(i_from, i_to, dtype=np.int64)
        return FogSamples(index, index / rate_hz, self.rate[s].copy(),
                          self.status_ok[s] & rec, rec, self.temp[s].copy())

    def discard_before(self, i: int) -> None:
        k = min(max(i - self.base, 0), self.n)
        if k == 0:
            return
        keep = self.n - k
        for name in ("rate", "status_ok", "received", "temp"):
            a = getattr(self, name)
            a[:keep] = a[k:self.n]
        self.base += k
        self.n = keep


def _capture_start(fmt: FrameFormat, first_index: int | None
                   ) -> tuple[StreamDecoder, _SampleStore]:
    """A decoder and a sample store before a capture's first byte: the one start shared by
    the live driver, `read_capture` and `CaptureCursor`, so all three index alike."""
    dec = StreamDecoder(fmt)
    dec.state = DecodeState.starting_at(first_index)
    store = _SampleStore()
    store.base = first_index or 0
    return dec, store


class Fog:
    """A FOG on a serial port, read continuously in the background.

    `rate_hz` is the FOG's output rate (from the stand file), `units` what its
    rotational data mean, `axis` which of x, y, z is the table axis's sensitive axis.
    Real-time waits are `timeout_s / min_speed(clock)` plus a margin (drivers/clock.py,
    drivers/waits.py).
    """

    @classmethod
    def from_settings(cls, settings: FogSettings, *, raw_path: Path | str | None,
                      clock: Clock, keep_samples: int | None = None) -> Fog:
        """The FOG a stand's `fog:` block declares (drivers/fog_settings.py), the settings
        object whole, as python-can's `Bus(**config)`: a FOG setting is read here, not
        copied field by field by each caller."""
        return cls(settings.port, baudrate=settings.baudrate, fmt=settings.format,
                   axis=settings.axis, rate_hz=settings.rate_hz, units=settings.units,
                   configure=settings.configure, raw_path=raw_path, clock=clock,
                   model=settings.model, keep_samples=keep_samples)

    def __init__(self, port: str, *, baudrate: int = 921600, fmt: str = "kvh-a",
                 axis: str = "z", rate_hz: float, units: str | None,
                 raw_path: Path | str | None, clock: Clock, model: str | None = None,
                 keep_samples: int | None = None,
                 configure: str = "declare",
                 wait_margin_s: float = MIN_REAL_MARGIN_S) -> None:
        if units is None:
            raise FogError(
                f"FOG on {port}: the stand names no fog.units; a KVH FOG's rotational data "
                "are delta radians after power-on (1775 IMU Technical Manual, Table 5-10), "
                "so the bench will not guess: set fog.units and fog.configure (set, verify "
                "or declare)")
        if configure not in MODES:
            raise FogError(f"FOG on {port}: fog.configure {configure!r}: one of "
                           f"{', '.join(MODES)}")
        self.configure = configure
        #: what the FOG read back at connect (fog.configure set or verify)
        self.readback: dict[str, str] = {}
        self.format: FrameFormat = get_format(fmt)
        if axis not in self.format.valid_bits:
            raise ValueError(f"FOG axis {axis!r} unknown for format {self.format.name!r} "
                             f"(one of {', '.join(self.format.valid_bits)})")
        if not rate_hz or rate_hz <= 0:
            raise ValueError(f"FOG rate_hz must be > 0, got {rate_hz!r}")
        self.port = port
        self.baudrate = int(baudrate)
        self.axis = axis
        self.rate_hz = float(rate_hz)
        self.units = units
        self._scale = dps_per_unit(units, self.rate_hz)
        self.raw_path = Path(raw_path) if raw_path is not None else None
        self.clock = clock
        self.model = model
        #: real seconds a wait allows beyond its scaled time, and of silence before it fails
        self.wait_margin_s = float(wait_margin_s)
        self._axis_col = AXES.index(axis)
        self._valid_mask = 1 << self.format.valid_bits[axis]
        self._ser: serial.Serial | None = None
        self._raw: IO[bytes] | None = None
        # the raw capture's SHA-256 and length, taken from the bytes as they are written
        # (None once a write failed: the file is then hashed from disk, if at all)
        self._raw_sha256: _Hash | None = None
        self._raw_bytes = 0
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._cond = threading.Condition()
        self._decoder = StreamDecoder(self.format)
        self._store = _SampleStore()
        # None: every sample stays readable; n: only the newest n or more (a long run's
        # memory must not grow with its length: the raw capture holds them all)
        self.keep_samples = keep_samples
        self._stalls: list[StallEvent] = []
        self._lag_s = math.nan
        self._lag_before: float | None = None
        self._alias_check: tuple[float, float, int, float] | None = None
        self.last_error: str | None = None
        self._index_uncertain_from: int | None = None
        #: the index the capture starts from (DecodeState.first_index); set by open()
        self.first_index: int | None = None

    # -- lifecycle ------------------------------------------------------------------------
    def open(self) -> Fog:
        """Open the port, configure (fog.configure), capture from the clock's now on."""
        if self._ser is not None:
            raise FogError(f"FOG on {self.port} is already open")
        try:
            self._ser = serial.Serial(self.port, self.baudrate, timeout=_READ_TIMEOUT_S)
        except (serial.SerialException, OSError) as e:
            raise FogError(f"cannot open FOG port {self.port}: {e}") from e
        if self.configure != "declare":
            try:
                self.readback = KvhConfigurator(_SerialLines(self._ser), port=self.port).apply(
                    KvhTarget(self.units, self.rate_hz,
                              self.format.name.rsplit("-", 1)[-1].upper(), self.configure))
                # what is left of the dialogue is not the record: the capture starts at
                # the first binary byte after Configuration Mode ends. On a stepped clock
                # nothing follows the last reply (the twin sends no frame before the
                # reader is counted, sims/clock.py), so the wait for stragglers is not
                # paid there (0.05 s of wall time an axis, issue 62)
                if not stepped(self.clock):
                    time.sleep(0.05)
                self._ser.reset_input_buffer()
            except (KvhConfigError, serial.SerialException, OSError) as e:
                self._ser.close()
                self._ser = None
                raise FogError(str(e)) from e
        if self.raw_path is not None:
            try:
                self.raw_path.parent.mkdir(parents=True, exist_ok=True)
                self._raw = open(self.raw_path, "wb")  # noqa: SIM115 (closed in close())
                self._raw_sha256, self._raw_bytes = hashlib.sha256(), 0
            except OSError as e:
                self._ser.close()
                self._ser = None
                raise FogError(f"cannot create the FOG raw capture {self.raw_path}: {e}") from e
        self.first_index = first_sample_after(self.clock.now(), self.rate_hz)
        with self._cond:
            self._decoder, self._store = _capture_start(self.format, self.first_index)
        self._stop.clear()
        channel_opened(self.clock, self.port)  # a stepped clock counts what we consume
        self._thread = threading.Thread(target=self._read_loop, name=f"fog-{self.port}",
                                        daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        self._caught_up()   # the capture holds every frame up to now, as it is closed
        self._stop.set()
        channel_closed(self.clock, self.port)
        if self._ser is not None:
            try:
                self._ser.cancel_read()
            except (serial.SerialException, OSError):
                pass
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        if self._ser is not None:
            self._ser.close()
            self._ser = None
        if self._raw is not None:
            raw, self._raw = self._raw, None
            try:
                raw.close()
            except OSError as e:
                self._raw_sha256 = None
                raise FogError(f"FOG on {self.port}: cannot write the raw capture "
                               f"{self.raw_path}: {e.strerror}") from e
            finally:
                with self._cond:
                    self._cond.notify_all()
        with self._cond:
            self._cond.notify_all()

    @property
    def is_open(self) -> bool:
        return self._ser is not None

    @property
    def raw_digest(self) -> tuple[str, int] | None:
        """(SHA-256 hex, bytes) of the raw capture as written, once closed: hashed on the
        way to the file, so a day's capture need not be read back to be hashed (None while
        open, without a capture, or after a failed write)."""
        if self._raw is not None or self._raw_sha256 is None:
            return None
        return self._raw_sha256.hexdigest(), self._raw_bytes

    def __enter__(self) -> Fog:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def identity(self) -> str:
        """FOGs answer no *IDN?: the model is what the stand file says; the serial is the
        unit's own answer to ?IS where it was asked at connect (configure set or
        verify), so a swapped FOG is found as a swapped counter is."""
        model = self.model or self.format.title
        how = {"set": "set and read back", "verify": "read back",
               "declare": "declared, not read back"}[self.configure]
        serial = self.readback.get("fog.serial")
        said = f", serial {serial} (?IS)" if serial else ""
        return f"{model}{said}; format {self.format.name}; axis {self.axis}; " \
               f"{self.rate_hz:g} Hz; {self.units} ({how}); {self.port} at {self.baudrate} Bd"

    # -- reader -----------------------------------------------------------------------------
    def _read_loop(self) -> None:
        ser = self._ser
        assert ser is not None
        silent_since: float | None = None
        # a stepped clock stands still while nothing waits on it: silence there is not
        # the FOG's (a hold on the clock's own time is seen as late samples, not here)
        stall_s = math.inf if stepped(self.clock) else \
            max(_STALL_FRAMES / self.rate_hz, _STALL_REAL_S * self.clock.speed)
        gap_s = _STEPPED_GAP_S if stepped(self.clock) else _BATCH_GAP_S
        coming = (lambda: in_flight(self.clock, self.port)) if stepped(self.clock) else None
        started = False
        buf = bytearray(_BATCH_BYTES)  # one buffer, refilled for every batch
        # a co-simulated FOG streams far faster than a real one's 921.6 kBd: its pty is
        # read by a pump process, not 4 kB a call here (drivers/port_pump.py)
        pump = PortPump.start(self.port) if stepped(self.clock) else None
        try:
            while not self._stop.is_set():
                if pump is not None:
                    data = _pumped(pump, buf, gap_s, coming)
                else:
                    first = ser.read(max(1, min(ser.in_waiting, _BATCH_BYTES)))
                    data = self._batch(ser, first, gap_s, buf, coming) if first else None
                if data:
                    if self._raw is not None:
                        try:
                            self._raw.write(data)
                            self._raw.flush()
                            if self._raw_sha256 is not None:  # releases the GIL
                                self._raw_sha256.update(data)
                                self._raw_bytes += len(data)
                        except OSError as e:
                            self._raw_sha256 = None
                            raise OSError(e.errno, f"cannot write the raw capture "
                                          f"{self.raw_path}: {e.strerror}") from e
                    now = self.clock.now()
                    resumed = None
                    if silent_since is not None and now - silent_since >= stall_s:
                        resumed = StallEvent(silent_since, now - silent_since,
                                             self._store.end - 1)
                        self._stalls.append(resumed)
                    silent_since = None
                    started = True
                    self._ingest(data, now, resumed)
                    consumed(self.clock, self.port, len(data))  # after it is readable
                elif silent_since is None and started:
                    silent_since = self.clock.now()
        except Exception as e:  # noqa: BLE001 (the reader must report, not vanish)
            if not self._stop.is_set():
                self.last_error = f"FOG reader on {self.port} stopped: {e}"
                # nothing reads the port any more: a stepped clock must not wait for it
                # (it would hold every step for its real-time guard until the abort)
                channel_closed(self.clock, self.port)
        finally:
            if pump is not None:
                pump.close()
            with self._cond:
                self._cond.notify_all()

    @staticmethod
    def _batch(ser: serial.Serial, first: bytes, gap_s: float = _BATCH_GAP_S,
               buf: bytearray | None = None, coming: Callable[[], int] | None = None
               ) -> memoryview:
        """More of what is arriving, up to _BATCH_BYTES or _BATCH_REAL_S.

        A pty or a USB adapter hands over a few kB a read (a pty's line discipline holds
        4 kB); decoding each piece on its own costs more than the bytes (a fixed cost of
        ~0.2 ms a call), so a fast stream is gathered first. How long:
        - a port that says "nothing now" with EAGAIN: up to _BATCH_GAP_S for the next
          piece, never holding a batch longer than _BATCH_REAL_S (a slow stream's latency);
        - a port that returns 0 bytes when empty (a tty as pyserial sets it, VMIN = 0 and
          VTIME = 0: every pty and USB adapter here): the batch ends there, as the same
          0 is what a port that is gone returns;
        - on a stepped clock, `coming()` says how many bytes the twin has sent that the
          driver has not reported consumed: while that is more than the batch holds, the
          rest of the burst is on its way (in the pty, or in the twin's writer) and the
          batch waits for it, up to _BATCH_BYTES. Measured on the paper ladder (2-core
          VM, 27 Nov 2026): without it most batches ended at the first empty moment of
          the pty (16-64 kB, the reader's decode calls costing more than its bytes);
          with it nearly all hold 512 kB, and the ladder took 131 s against 167 s, CPU
          194 against 247 core-s.
        The pieces are read straight into `buf` (reused from batch to batch: no copy, no
        allocation per piece); the view returned is valid until the next call.
        """
        if buf is None or len(buf) < len(first):
            buf = bytearray(max(_BATCH_BYTES, len(first)))
        view = memoryview(buf)
        size = len(first)
        view[:size] = first
        fd = _nonblocking_fd(ser)
        if fd is not None:
            return view[:_gather(fd, view, size, gap_s, coming)]
        cap = len(buf)
        while size < cap:  # a port without a descriptor (not POSIX): through pyserial
            w = ser.in_waiting
            more = ser.read(min(w, cap - size)) if w else b""
            if not more:
                break
            view[size:size + len(more)] = more
            size += len(more)
        return view[:size]

    def _ingest(self, data: bytes | memoryview, now: float, resumed: StallEvent | None) -> None:
        with self._cond:
            frames = self._decoder.feed(data)
            if len(frames):
                self._store.add(frames, self._axis_col, self._scale, self._valid_mask)
                if self.keep_samples is not None and self._store.n > 2 * self.keep_samples:
                    self._store.discard_before(self._store.end - self.keep_samples)
                self._watch_clock(now, resumed)
            self._cond.notify_all()

    def _watch_clock(self, now: float, resumed: StallEvent | None) -> None:
        """Flag frames lost in whole counter wraps, which the bytes cannot show.

        lag = now - t(newest sample) is the chain's latency (plus a constant offset on a
        real bench). After a silence it is large until the backlog has arrived; if frames
        were lost in whole wraps of the sequence counter it stays large by that many frame
        periods. So after each silence longer than half a wrap, the smallest lag seen over
        the following `_ALIAS_WINDOW_S` is compared with the lag before the silence. The
        check needs real-time jitter well under half a wrap: it is armed only when half a
        wrap lasts at least `_ALIAS_MIN_REAL_S` real seconds.
        """
        lag = now - (self._store.end - 1) / self.rate_hz
        self._lag_s = lag
        half_wrap_s = 0.5 * self.format.sequence_modulus / self.rate_hz
        if half_wrap_s / self.clock.speed < _ALIAS_MIN_REAL_S:
            return
        if resumed is not None and resumed.duration_s >= half_wrap_s \
                and self._lag_before is not None:
            self._alias_check = (now, self._lag_before, resumed.after_index, lag)
        if self._alias_check is not None:
            t0, before, after_index, low = self._alias_check
            low = min(low, lag)
            self._alias_check = (t0, before, after_index, low)
            if now - t0 >= _ALIAS_WINDOW_S * self.clock.speed:
                self._alias_check = None
                if low - before > half_wrap_s:
                    frames = round((low - before) * self.rate_hz)
                    self._index_uncertain_from = after_index + 1
                    self.last_error = (
                        f"FOG on {self.port}: after the silence following sample "
                        f"{after_index} the samples trail the clock by {frames} frames more "
                        f"than before, but the sequence counter shows fewer lost: frames "
                        f"were lost in whole counter wraps ({self.format.sequence_modulus}) "
                        f"and every index after {after_index} is uncertain")
        if self._alias_check is None:
            self._lag_before = lag

    # -- what the engine reads --------------------------------------------------------------
    def _caught_up(self) -> None:
        """Before any reading: on a stepped clock the twin's frames up to now are read and
        decoded first (drivers/clock.py settle_channel), so a reading at stand time t sees
        exactly what the FOG sent up to t, however the threads were scheduled."""
        if self._thread is not None:
            settle_channel(self.clock, self.port)

    @property
    def end_index(self) -> int:
        """One past the newest sample known (received, or known lost)."""
        self._caught_up()
        with self._cond:
            return self._store.end

    def wait_for_index(self, i: int, timeout_s: float) -> None:
        """Block until sample i is known.

        The limit is `timeout_s` on the clock scaled to real time plus a margin of at least
        `wait_margin_s` (drivers/waits.py), and it is only reached once the stream has
        also been silent for that margin: samples still arriving late mean a slow host
        (or a twin behind its clock), which slows the run but must not abort it, up to
        `MAX_LATE_REAL_S` beyond the limit (a stream that never catches up is a fault).
        On a stepped clock the wait is on clock time (drivers/waits.py): the clock passes
        to when sample i is due, and the limit is `timeout_s` of clock time.
        """
        if stepped(self.clock):
            self._wait_stepped(i, timeout_s)
            return
        start = time.monotonic()
        deadline = start + real_budget_s(self.clock, timeout_s) + self.wait_margin_s
        last_end, last_progress = -1, start
        ok = True
        with self._cond:
            while True:
                done = self._cond.wait_for(
                    lambda: self._store.end > i or self._thread is None
                    or not self._thread.is_alive(),
                    timeout=max(min(deadline - time.monotonic(), 0.5), 0.01))
                if self._store.end > i:
                    return
                if done:        # the reader has stopped
                    break
                now = time.monotonic()
                if self._store.end != last_end:
                    last_end, last_progress = self._store.end, now
                if now >= deadline and (now - last_progress >= self.wait_margin_s
                                        or now >= deadline + MAX_LATE_REAL_S):
                    ok = False
                    break
        if self.last_error:
            raise FogError(self.last_error)
        if not ok:
            raise FogTimeout(
                f"FOG on {self.port}: sample {i} (t = {i / self.rate_hz:.4f} s) did not arrive "
                f"within {timeout_s:g} s; newest sample {self._store.end - 1}, "
                f"{self._decoder.bytes} bytes received")
        raise FogError(f"FOG on {self.port} is not open")

    def _wait_stepped(self, i: int, timeout_s: float) -> None:
        def due_in_s() -> float:  # clock time until sample i is due at the FOG's rate
            self._caught_up()
            with self._cond:
                due = (i + 1 - self._store.end) / self.rate_hz
            return due if due > 0 else _LATE_STEP_S  # due, not there: held up (a stall)

        def known() -> bool:
            self._caught_up()
            with self._cond:
                return self._store.end > i or self._thread is None \
                    or not self._thread.is_alive()

        wait_on_clock(self.clock, known, due_in_s() + timeout_s, due_in_s)
        if self.last_error:
            raise FogError(self.last_error)
        with self._cond:
            if self._store.end > i:
                return
        if self._thread is None or not self._thread.is_alive():
            raise FogError(f"FOG on {self.port} is not open")
        raise FogTimeout(
            f"FOG on {self.port}: sample {i} (t = {i / self.rate_hz:.4f} s) did not arrive "
            f"within {timeout_s:g} s; newest sample {self._store.end - 1}, "
            f"{self._decoder.bytes} bytes received")

    def checkpoint(self) -> FogCheckpoint:
        """Where the decoder stands in the raw capture now (JSON-able).

        A CaptureCursor started from it decodes the rest of the capture exactly as from
        the file's beginning, without reading what lies before: an hour into a run, the
        analysis of the next window need not re-decode the hour.
        """
        self._caught_up()
        with self._cond:
            s = self._decoder.state
        return {"offset": s.offset, "last_index": s.last_index,
                "last_sequence": s.last_sequence, "last_end": s.last_end,
                "first_index": s.first_index}

    def samples(self, i_from: int, i_to: int) -> FogSamples:
        """Samples i_from .. i_to - 1; they must have arrived and not been discarded."""
        self._caught_up()
        with self._cond:
            return self._store.samples(i_from, i_to, self.rate_hz)

    def discard_before(self, i: int) -> None:
        self._caught_up()
        with self._cond:
            self._store.discard_before(i)

    @property
    def stats(self) -> FogStats:
        self._caught_up()
        d = self._decoder
        with self._cond:
            r = self.rate_hz
            return FogStats(
                frames=d.frames, crc_errors=d.crc_errors, gaps=d.gaps,
                lost_frames=d.lost_frames, skipped_bytes=d.skipped_bytes, bytes=d.bytes,
                crc_events=tuple(CrcEvent(i, i / r, o) for i, o in d.crc_events),
                gap_events=tuple(GapEvent(i, c, i / r) for i, c in d.gap_events),
                stalls=tuple(self._stalls), lag_s=self._lag_s,
                index_uncertain_from=self._index_uncertain_from)

    @property
    def health(self) -> str:
        """"ok", "degraded" (frames lost or broken, stalls) or "error" (no trustworthy data)."""
        self._caught_up()
        if self.last_error or (self._thread is not None and not self._thread.is_alive()):
            return "error"
        d = self._decoder
        if d.crc_errors or d.gaps or self._stalls:
            return "degraded"
        return "ok"



class _SerialLines:
    """A pyserial port as the line link drivers/kvh_config.py talks through."""

    def __init__(self, ser: serial.Serial) -> None:
        self.ser = ser
        #: a line begun when a read's time ran out: the rest comes with the next read (a
        #: reply cut at the deadline and returned in two halves matched neither: a loaded
        #: CI machine saw "no answer starting 'ROTFMT,RATE'")
        self._partial = bytearray()

    def write(self, data: bytes) -> None:
        self.ser.write(data)
        self.ser.flush()

    def read(self, timeout_s: float) -> bytes:
        """One whole line, or b"" when none was completed within `timeout_s`."""
        deadline = time.monotonic() + timeout_s
        line = self._partial
        while time.monotonic() < deadline:
            b = self.ser.read(1)
            if b in (b"\n", b"\r"):
                if line:
                    self._partial = bytearray()
                    return bytes(line)
                continue
            line.extend(b)
        self._partial = line
        return b""


def read_capture(raw_path: Path | str, *, fmt: str = "kvh-a", axis: str = "z",
                 rate_hz: float, units: str = "deg/s", chunk_bytes: int = _CAPTURE_CHUNK_BYTES,
                 first_index: int | None = None) -> tuple[FogSamples, StreamDecoder]:
    """Every sample of a raw capture, exactly as the live driver produced them.

    For `bench analyze`: the same decoder and the same frame-to-sample conversion as
    `Fog`, so the result is bit-identical to what `Fog.samples` returned during the run.
    Returns the samples from the first (index 0, or `first_index` for a FOG opened
    while the clock ran: its `fog_capture` event says) to the last frame, and the
    decoder with the counts and events (CRC failures, gaps) of the whole capture.
    """
    f = get_format(fmt)
    if axis not in f.valid_bits:
        raise ValueError(f"FOG axis {axis!r} unknown for format {f.name!r}")
    dec, store = _capture_start(f, first_index)
    col, scale, mask = AXES.index(axis), dps_per_unit(units, rate_hz), 1 << f.valid_bits[axis]
    with open(raw_path, "rb") as fh:
        while chunk := fh.read(chunk_bytes):
            store.add(dec.feed(chunk), col, scale, mask)
    return store.samples(store.base, store.end, float(rate_hz)), dec


class CaptureCursor:
    """A raw capture read forward in chunks: the samples of index windows, in order.

    For analysing a long run: the decoder runs once over the file, from where the last
    window ended to where the next one ends, and only about `chunk_bytes` of frames are
    decoded and held at a time, however long the capture. The same decoder and the same
    frame-to-sample conversion as `Fog` and `read_capture`, so the samples are
    bit-identical to theirs. The file may still be growing (a live run): a window is
    read once its bytes are in the file.
    """

    def __init__(self, raw_path: Path | str, *, fmt: str = "kvh-a", axis: str = "z",
                 rate_hz: float, units: str = "deg/s", chunk_bytes: int = _CAPTURE_CHUNK_BYTES,
                 start: FogCheckpoint | None = None, first_index: int | None = None
                 ) -> None:
        f = get_format(fmt)
        if axis not in f.valid_bits:
            raise ValueError(f"FOG axis {axis!r} unknown for format {f.name!r}")
        self.raw_path = Path(raw_path)
        self.rate_hz = float(rate_hz)
        # the file's start: index 0, or the capture's first_index (a late open)
        self.decoder, self._store = _capture_start(f, first_index)
        self._col, self._scale = AXES.index(axis), dps_per_unit(units, rate_hz)
        self._mask = 1 << f.valid_bits[axis]
        self._chunk_bytes = int(chunk_bytes)
        self._fh: IO[bytes] = open(self.raw_path, "rb")  # noqa: SIM115 (closed in close())
        if start is not None:  # a Fog.checkpoint(): continue the decoder from there
            self.decoder.state = state = _decode_state(start)
            self._fh.seek(state.offset)
            self._store.base = state.last_index + 1

    @property
    def position(self) -> int:
        """The first sample index still readable (windows must start at or after it)."""
        return self._store.base

    def close(self) -> None:
        self._fh.close()

    def _more(self) -> bool:
        data = self._fh.read(self._chunk_bytes)
        if data:
            self._store.add(self.decoder.feed(data), self._col, self._scale, self._mask)
        return bool(data)

    def window(self, i_from: int, i_to: int, chunk: int = 1 << 16) -> Iterator[FogSamples]:
        """Samples i_from .. i_to - 1 (lost ones as invalid rows), `chunk` at a time."""
        if i_from < self._store.base:
            raise ValueError(f"{self.raw_path}: samples before {self._store.base} are "
                             f"already passed (asked from {i_from}); open a new cursor")
        at = i_from
        while at < i_to:
            self._store.discard_before(at)
            hi = min(at + chunk, i_to)
            while self._store.end < hi and self._more():
                self._store.discard_before(at)
            if self._store.end < hi:
                raise ValueError(f"{self.raw_path}: FOG samples {i_from}..{i_to} are not all "
                                 f"in the capture (it ends at sample {self._store.end})")
            yield self._store.samples(at, hi, self.rate_hz)
            at = hi
        self._store.discard_before(i_to)
