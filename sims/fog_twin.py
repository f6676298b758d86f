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

The twin is a chain of classes, bottom up: sims/fog_settings.py `FogSettings` (the
configuration dialogue), sims/fog_line.py `FogLine` (the pty, the writer, the clock),
sims/fog_samples.py `FogSamples` (the frames of the stand's samples, the faults), and
`FogTwin` here (its construction, the faults' schedule, the truth, the life cycle).
"""

from __future__ import annotations

import os
import threading
from collections import deque
from dataclasses import dataclass

import numpy as np

from drivers.fog import dps_per_unit
from drivers.fog_formats import AXES, get_format
from drivers.fog_settings import FogSettings as StandFog
from drivers.kvh_config import POWER_ON_UNITS
from sims.fog_faults import Corrupt, Drop, Fault, Garbage, Stall
from sims.fog_samples import (
    ACCEL_NOISE_G,
    TEMPERATURE_NOISE_C,
    WARM_UP_C,
    WARM_UP_TAU_S,
    FogSamples,
)
from sims.stand import SimulatedStand
from sims.truth import FogTruth

__all__ = ["ACCEL_NOISE_G", "DEFAULT_SERIAL", "TEMPERATURE_NOISE_C", "WARM_UP_C",
           "WARM_UP_TAU_S", "Corrupt", "Drop", "Fault", "FogTwin", "Garbage", "Stall",
           "TwinTruth", "power_on_units"]

#: what `?IS` answers when the twin is given no serial (ICD 8.20: "a text string,
#: typically with a numeric value")
DEFAULT_SERIAL = "0"


def power_on_units(settings: StandFog | None, truth: FogTruth) -> str:
    """What the FOG twin carries before the bench talks to it: the truth's `fog.units`,
    else a declared `fog.units` (a FOG configured earlier), else the KVH power-on
    default, delta radians (drivers/kvh_config.py)."""
    if truth.units:
        return truth.units
    if settings is not None and settings.configure == "declare":
        return settings.units
    return POWER_ON_UNITS


@dataclass(frozen=True)
class TwinTruth:
    """What the twin did for samples i_from .. i_to - 1."""

    index: np.ndarray
    fog_dps: np.ndarray     # the stand's FOG output, float64
    value: np.ndarray       # the float32 put in the frame (in the frame's units)
    rate_dps: np.ndarray    # value converted back to deg/s as a driver must
    sent: np.ndarray        # the frame went out (not dropped, not lost to a stall)
    intact: np.ndarray      # ... and was not corrupted


class FogTwin(FogSamples):
    """Frames of one stand axis's FOG on a pty. Create it before the stand clock starts."""

    def __init__(self, stand: SimulatedStand, axis: str, settings: StandFog | None = None,
                 *, temperature: float = 25.0, keep_truth: bool = False) -> None:
        """`settings`: the stand's FOG block, as the driver takes it (its frame format,
        axis letter, serial, and the units a FOG configured earlier holds; None: a KVH
        A-format FOG on z at its power-on units); what it carries before the bench talks
        to it is the axis's truth's (`fog.units`) when stated (`power_on_units`)."""
        fmt = settings.format if settings is not None else "kvh-a"
        axis_letter = settings.axis if settings is not None else "z"
        serial = (settings.serial if settings is not None else None) or DEFAULT_SERIAL
        units = power_on_units(settings, stand.axis(axis).truth.fog)
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
        self._carry = []
        #: stand samples [start, end) while in Configuration Mode: never sent (end None:
        #: still in it)
        self._quiet = []
        self._tables_now = None
        self._temperature_terms = {}
        self._inbuf = bytearray()
        self.commands = []  # every line received (tests)
        #: the ambient the unit's temperature starts from, deg C (it warms up: _side)
        self.temperature = float(temperature)
        self.keep_truth = keep_truth
        self._faults = []
        self._queue = deque()
        self._sent_n = 0          # frames up to this stand sample are out on the port
        self._reading = False     # a reader has the port open
        self._slow = None  # (frames/real s, since, sent)
        self._qlock = threading.Lock()
        self._next_sample = 0
        self._truth = []
        self._master = None
        self._thread = None
        self._stop = threading.Event()
        self._wake = threading.Event()   # frames queued: the writer need not wait a tick
        self._wake_fds = None
        self._asleep = False
        self._gate_open = False          # a reader settled on the port, the clock runs
        self._queued_bytes = 0
        self._stepped = bool(getattr(self.clock, "stepped", False))
        self._leave = None
        self._presence = None  # the master, polled for a reader
        self.path = None
        self.bytes_written = 0
        self.frames_encoded = 0
        self._pending = []
        self._pending_n = 0
        with self.axis.lock:
            if self.axis.samples_generated:
                raise RuntimeError(
                    f"FOG twin for axis {axis!r} created after the stand generated "
                    f"{self.axis.samples_generated} samples: create it before anything "
                    f"advances the axis (the clock, command_rate), so frame n is stand "
                    f"sample n")
            self.axis.listeners.append(self._on_chunk)

    @property
    def next_sample(self) -> int:
        """The first stand sample not yet encoded: a fault must lie at or after it."""
        self._encode_pending()
        with self.axis.lock:
            return self._next_sample

    def inject(self, *faults: Fault) -> None:
        """Schedule faults by stand sample; each must lie ahead of what is already encoded."""
        self._encode_pending()
        with self.axis.lock:
            for f in faults:
                if f.sample < self._next_sample:
                    raise ValueError(f"{f} is in the past: samples up to "
                                     f"{self._next_sample - 1} are already encoded")
                self._faults.append(f)

    def stop(self) -> None:
        self._stop.set()
        self._rouse()
        if self._leave is not None:
            self._leave()
            self._leave = None
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        if self._master is not None:
            os.close(self._master)
            self._master = None
        if self._wake_fds is not None:
            for fd in self._wake_fds:
                os.close(fd)
            self._wake_fds = None
        with self.axis.lock:
            if self._on_chunk in self.axis.listeners:
                self.axis.listeners.remove(self._on_chunk)

    def __enter__(self) -> FogTwin:
        if self._thread is None:
            self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

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
