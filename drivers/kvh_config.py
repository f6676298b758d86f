"""KVH FOG/IMU configuration over its serial port: what the frames carry, set or verified.

Why: the rotational fields of every KVH output format are "Radians or degrees,
selectable ... delta angle or rate of rotation, selectable", and the factory default is
delta radians (1775 IMU Technical Manual 54-0938 / ICD 56-0298 Rev. B, Table 5-2 and
Table 5-10: "Configuration dependent (default: delta radians)"; the DSP-1760 technical
manual 54-1210 says the same of its format A). A driver that assumes deg/s reads a
1000 Hz delta-radian stream about 57 000 times too small. So the stand says what the
FOG carries (`fog.units`) and whether the bench `set`s it at connect, only `verify`s
it, or `declare`s it (trusted, nothing sent).

The protocol, from the 1775 ICD section 7 ("Commands and Queries", p. 24-25) and 3.3
(operating modes): ASCII lines ended by CR and/or LF; `=NAME,args` commands answer with
the same text without the '=' (so `=DR,1000` answers `DR,1000`); `?NAME` queries answer
`NAME,value`; in Configuration Mode an unknown command answers `INVALID,...`. The unit
stops its binary output in Configuration Mode and resumes it on leaving. Data rate:
`=DR,<1|5|10|25|50|100|250|500|750|1000|3600|5000>` and `?DR` (section 8.8, 8.9, p. 33).

Unverified (the stored manual pages we could read do not show them): the exact spelling
of the words that enter Configuration Mode and select the rotational format and units,
and of =LINFMT, =LINUNITS, =TEMPUNITS and =FILTEN (their queries' answers follow the
`NAME,value` pattern of ?LINUNITS, ICD 8.24, and ?FILTTYPE, ICD 8.17).
We use `=CONFIG,1` / `=CONFIG,0`, `=ROTFMT,<DELTA|RATE>`, `=ROTUNITS,<DEG|RAD>` and
`=OUTPUTFMT,<A|B|C>` as the 1750/1775 ICDs are cited by KVH users (the same pattern as
the accelerometers' `=LINFMT` and `?LINUNITS` -> `LINUNITS,<METERS|FEET>`, ICD 8.24,
which we could read); a unit that spells
them otherwise answers INVALID, which this module reports by name at connect, so a wrong
word is found on the first connection, never in a result.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

#: the power-on default of the rotational fields (Table 5-10: "default: delta radians")
POWER_ON_UNITS = "rad"
#: data rates the unit accepts (1775 ICD 8.8)
DATA_RATES_HZ = (1, 5, 10, 25, 50, 100, 250, 500, 750, 1000, 3600, 5000)
#: our unit names <-> (ROTFMT, ROTUNITS)
UNIT_WORDS: dict[str, tuple[str, str]] = {
    "deg/s": ("RATE", "DEG"), "rad/s": ("RATE", "RAD"),
    "deg": ("DELTA", "DEG"), "rad": ("DELTA", "RAD"),
}
MODES = ("set", "verify", "declare")


@dataclass(frozen=True)
class KvhWords:
    """Command names as data: the driver sends them, the twin parses them."""

    config: str = "CONFIG"
    data_rate: str = "DR"
    rot_format: str = "ROTFMT"
    rot_units: str = "ROTUNITS"
    output_format: str = "OUTPUTFMT"
    # what users' own scripts also send (1775 ICD section 8)
    baud: str = "BAUD"            # 8.3/8.4 (p. 30-31): =BAUD,<n> / ?BAUD -> BAUD,<n>
    lin_format: str = "LINFMT"    # 8.2x: accelerations in g (default) or delta velocity
    lin_units: str = "LINUNITS"   # 8.24 (p. 46): ?LINUNITS -> LINUNITS,<METERS|FEET>
    temp_units: str = "TEMPUNITS"  # temperature field: degrees C or F (Table 5-2)
    filter_enable: str = "FILTEN"  # =FILTEN,<A|G>,<0|1> / ?FILTEN,<A|G> (unverified)
    reset_config: str = "RSTCFG"  # factory configuration; the baud rate stays (Table 9-x
    #                               note 1, p. 56 of the ICD)
    serial_number: str = "IS"     # 8.20 (p. 44): ?IS -> IS,<serial number> ("a text
    #                               string, typically with a numeric value")


#: the accepted baud rates (ICD 8.3)
BAUD_RATES = (9600, 19200, 38400, 57600, 115200, 460800, 576000, 921600, 4147200)
#: linear (accelerometer) data: (LINFMT, LINUNITS) words; g is the power-on default
LIN_FORMATS = ("ACCEL", "DELTA")
LIN_UNITS = ("METERS", "FEET")
TEMP_UNITS = ("C", "F")
#: standard gravity, m/s^2: a unit at rest with its axis up reads +1 g on it (ICD
#: Table 9-x note 4, "+1 G due to Earth gravity when its positive axis is up")
G0_MPS2 = 9.80665
FEET_PER_METER = 1.0 / 0.3048


WORDS = KvhWords()


def units_of(rot_format: str, rot_units: str) -> str:
    """Our unit name for a (ROTFMT, ROTUNITS) pair."""
    for name, pair in UNIT_WORDS.items():
        if pair == (rot_format.upper(), rot_units.upper()):
            return name
    raise ValueError(f"unknown rotational format {rot_format!r}/{rot_units!r}")


class KvhConfigError(RuntimeError):
    """The FOG's configuration is not what the stand says (names the stand key)."""


class LineLink(Protocol):
    def write(self, data: bytes) -> None: ...

    def read(self, timeout_s: float) -> bytes: ...


@dataclass(frozen=True)
class KvhTarget:
    """What the stand says the FOG must carry."""

    units: str
    rate_hz: float
    frame_format: str  # "A", "B" or "C"
    mode: str = "declare"


class KvhConfigurator:
    """Enter Configuration Mode, set and/or read back, leave it (module docstring)."""

    def __init__(self, link: LineLink, *, port: str = "", timeout_s: float = 1.0,
                 log: Callable[[str, str], None] | None = None) -> None:
        self.link = link
        self.port = port
        self.timeout_s = timeout_s
        self.log = log

    def _exchange(self, line: str, expect_prefix: str) -> str:
        self.link.write((line + "\r\n").encode("ascii"))
        if self.log:
            self.log("tx", line)
        for _ in range(16):  # skip stray binary bytes and empty lines before the answer
            raw = self.link.read(self.timeout_s)
            text = raw.decode("ascii", "replace").strip("\r\n\x00 ")
            if self.log:
                self.log("rx", text)
            if text.upper().startswith("INVALID"):
                raise KvhConfigError(f"FOG on {self.port}: {line!r} answered {text!r}: the "
                                     "unit does not know this word (drivers/kvh_config.py "
                                     "lists the unverified ones)")
            if text.upper().startswith(expect_prefix.upper()):
                return text
        raise KvhConfigError(f"FOG on {self.port}: no answer starting {expect_prefix!r} "
                             f"to {line!r}")

    def command(self, name: str, *args: object) -> str:
        body = ",".join([name, *map(str, args)])
        return self._exchange("=" + body, body)

    def query(self, name: str) -> str:
        reply = self._exchange("?" + name, name + ",")
        return reply.split(",", 1)[1].strip()

    def apply(self, want: KvhTarget) -> dict[str, str]:
        """Set (mode 'set') and read back (set, verify); returns what the FOG reads back.

        Raises KvhConfigError naming the stand key that disagrees.
        """
        if want.mode == "declare":
            return {}
        if want.units not in UNIT_WORDS:
            raise KvhConfigError(f"fog.units {want.units!r}: one of {', '.join(UNIT_WORDS)}")
        w = WORDS
        fmt, units = UNIT_WORDS[want.units]
        self.command(w.config, 1)
        try:
            if want.mode == "set":
                self.command(w.output_format, want.frame_format)
                self.command(w.rot_format, fmt)
                self.command(w.rot_units, units)
                self.command(w.data_rate, int(want.rate_hz))
            got = {"fog.format": self.query(w.output_format),
                   "fog.units": units_of(self.query(w.rot_format), self.query(w.rot_units)),
                   "fog.rate_hz": self.query(w.data_rate)}
            # its identity (8.20, p. 44: ?IS -> IS,<serial number>): compared with the
            # stand's fog.serial; a unit that does not know the word keeps the stated one
            try:
                serial = self.query(w.serial_number)
            except KvhConfigError:
                serial = ""
            if serial and serial.strip("0 "):
                got["fog.serial"] = serial
        finally:
            self.command(w.config, 0)
        problems = []
        if got["fog.format"].upper() != want.frame_format.upper():
            problems.append(f"fog.format: the stand says {want.frame_format}, the FOG "
                            f"outputs format {got['fog.format']}")
        if got["fog.units"] != want.units:
            problems.append(f"fog.units: the stand says {want.units}, the FOG outputs "
                            f"{got['fog.units']}")
        if float(got["fog.rate_hz"]) != float(want.rate_hz):
            problems.append(f"fog.rate_hz: the stand says {want.rate_hz:g}, the FOG outputs "
                            f"{got['fog.rate_hz']} Hz")
        if problems:
            raise KvhConfigError(f"FOG on {self.port} (fog.configure: {want.mode}): "
                                 + "; ".join(problems))
        return got
