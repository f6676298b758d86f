"""The FOG twin's configuration dialogue (drivers/kvh_config.py, 1775 IMU ICD sections
3.3, 7 and 8): the unit's settings and the answers to `=NAME,value` and `?NAME` in
Configuration Mode, as sims/fog_twin.py's docstring describes.

The lowest class of the twin's chain: what it holds is read by the line below it
(sims/fog_line.py) and by the frame encoding (sims/fog_samples.py).
"""

from __future__ import annotations

from drivers.fog import dps_per_unit, first_sample_after
from drivers.fog_formats import FrameFormat, get_format
from drivers.kvh_config import (
    BAUD_RATES,
    DATA_RATES_HZ,
    LIN_FORMATS,
    LIN_UNITS,
    POWER_ON_UNITS,
    TEMP_UNITS,
    UNIT_WORDS,
    WORDS,
    units_of,
)
from sims.clock import SteppedClock, VirtualClock
from sims.stand import AxisModel, SimulatedStand


class FogSettings:
    """What the unit is configured to send, and the dialogue that changes it (ICD 7)."""

    #: set by FogTwin.__init__ (sims/fog_twin.py)
    serial: str
    stand: SimulatedStand
    axis: AxisModel
    clock: VirtualClock | SteppedClock
    rate_hz: float
    format: FrameFormat
    frame_letter: str
    units: str
    _dps_per_unit: float
    config_mode: bool
    data_rate_hz: int
    baud: int
    lin_format: str
    lin_units: str
    temp_units: str
    filter_enabled: dict[str, bool]
    #: stand samples [start, end) while in Configuration Mode: never sent (end None:
    #: still in it)
    _quiet: list[tuple[int, int | None]]

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
