"""CiA 402 (IEC 61800-7-201) drive profile as data: objects, bits, states, modes, units.

The driver (drivers/axis.py) and the drive twin (sims/drive_twin.py) both read these
tables, so the two ends cannot disagree about what a bit or an index means. The
object dictionary itself lives in drivers/profiles/bench-drive.eds (both ends load it);
this module names the objects the code touches.

Sources: CiA 301 (heartbeat, EMCY, identity), CiA 402 part 2 (state machine, modes,
controlword and statusword), as restated in the drive manuals of Nanotec, Kollmorgen
and Synapticon; where a drive's option codes differ, the EDS default says ours.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum, IntEnum

from drivers.profiles import EDS_NAME, profile_path

#: this project's EDS: a CiA 402 servo drive with profile velocity mode
DEFAULT_EDS_PATH = profile_path(EDS_NAME)
#: encoder increments per revolution where the stand file states none (a 20-bit encoder)
DEFAULT_COUNTS_PER_REV = 1 << 20

#: CiA 301 0x1000: profile 402 (low word), servo drive (0x0002 in the high word)
DEVICE_TYPE_SERVO_402 = 0x0002_0192


class Od(IntEnum):
    """Object dictionary indices the driver and the twin use."""

    DEVICE_TYPE = 0x1000
    ERROR_REGISTER = 0x1001
    DEVICE_NAME = 0x1008
    HARDWARE_VERSION = 0x1009
    SOFTWARE_VERSION = 0x100A
    CONSUMER_HEARTBEAT = 0x1016  # sub 1: (producer node id << 16) | time_ms
    PRODUCER_HEARTBEAT = 0x1017  # ms
    IDENTITY = 0x1018  # subs 1..4: vendor, product, revision, serial
    RPDO1_COMM = 0x1400
    RPDO1_MAP = 0x1600
    TPDO1_COMM = 0x1800
    TPDO1_MAP = 0x1A00
    ABORT_CONNECTION_OPTION = 0x6007
    ERROR_CODE = 0x603F
    CONTROLWORD = 0x6040
    STATUSWORD = 0x6041
    QUICK_STOP_OPTION = 0x605A
    SHUTDOWN_OPTION = 0x605B
    DISABLE_OPERATION_OPTION = 0x605C
    HALT_OPTION = 0x605D
    FAULT_REACTION_OPTION = 0x605E
    MODES_OF_OPERATION = 0x6060
    MODES_OF_OPERATION_DISPLAY = 0x6061
    POSITION_ACTUAL = 0x6064  # position units (counts here)
    POSITION_WINDOW = 0x6067  # position units; statusword bit 10 in PP
    POSITION_WINDOW_TIME = 0x6068  # ms
    VELOCITY_ACTUAL = 0x606C  # velocity units
    VELOCITY_WINDOW = 0x606D  # velocity units; statusword bit 10 in PV
    VELOCITY_WINDOW_TIME = 0x606E  # ms
    VELOCITY_THRESHOLD = 0x606F  # velocity units; statusword bit 12 in PV
    VELOCITY_THRESHOLD_TIME = 0x6070  # ms
    TARGET_POSITION = 0x607A  # position units; taken on controlword bit 4 in PP
    MAX_PROFILE_VELOCITY = 0x607F
    PROFILE_VELOCITY_PP = 0x6081  # velocity units; the cruise rate of a PP move
    PROFILE_ACCELERATION = 0x6083  # acceleration units
    PROFILE_DECELERATION = 0x6084
    QUICK_STOP_DECELERATION = 0x6085
    POSITION_ENCODER_RESOLUTION = 0x608F  # sub 1 increments, sub 2 motor revolutions
    GEAR_RATIO = 0x6091  # sub 1 motor revolutions, sub 2 shaft revolutions
    FEED_CONSTANT = 0x6092  # sub 1 feed, sub 2 shaft revolutions
    VELOCITY_FACTOR = 0x6096  # sub 1 numerator, sub 2 divisor
    ACCELERATION_FACTOR = 0x6097  # sub 1 numerator, sub 2 divisor
    SI_UNIT_VELOCITY = 0x60A9  # prefix, unit, time, 0 (one byte each, high to low)
    SI_UNIT_ACCELERATION = 0x60AA  # prefix, unit, time, time
    MAX_ACCELERATION = 0x60C5
    MAX_DECELERATION = 0x60C6
    TARGET_VELOCITY = 0x60FF
    SUPPORTED_DRIVE_MODES = 0x6502


#: COB-ID bases of CiA 301's predefined connection set (+ node id)
COB_SYNC = 0x080
COB_EMCY = 0x080
COB_HEARTBEAT = 0x700
CONTROLLER_NODE_ID = 0x7F     # the controller's (NMT master's) usual node id
NMT_STATE_OPERATIONAL = 0x05

# -- controlword (0x6040) ------------------------------------------------------------


class Cw(IntEnum):
    """Controlword bits."""

    SWITCH_ON = 1 << 0
    ENABLE_VOLTAGE = 1 << 1
    QUICK_STOP = 1 << 2  # active low: 0 requests a quick stop
    ENABLE_OPERATION = 1 << 3
    NEW_SET_POINT = 1 << 4  # profile position: take 0x607A on the rising edge
    CHANGE_SET_IMMEDIATELY = 1 << 5  # profile position: abandon the move under way
    RELATIVE = 1 << 6  # profile position: 0x607A relative to the present target
    FAULT_RESET = 1 << 7  # acts on its rising edge
    HALT = 1 << 8


class Command(Enum):
    """Device-control commands: (mask, value) of the controlword's bits 0-3 and 7."""

    SHUTDOWN = (0x87, 0x06)
    SWITCH_ON = (0x8F, 0x07)  # also "disable operation"
    ENABLE_OPERATION = (0x8F, 0x0F)  # also "switch on + enable operation"
    DISABLE_VOLTAGE = (0x82, 0x00)
    QUICK_STOP = (0x86, 0x02)
    FAULT_RESET = (0x80, 0x80)

    @property
    def word(self) -> int:
        """The controlword that issues this command (other bits zero)."""
        return self.value[1]


#: decode order matters: a word with bit 1 clear is "disable voltage" whatever bits 0, 2, 3 say
_DECODE_ORDER = (Command.DISABLE_VOLTAGE, Command.QUICK_STOP, Command.SHUTDOWN,
                 Command.SWITCH_ON, Command.ENABLE_OPERATION)


def decode_command(controlword: int) -> Command | None:
    """The device-control command a controlword carries (fault reset is an edge: not here)."""
    for cmd in _DECODE_ORDER:
        mask, value = cmd.value
        if controlword & mask & 0x0F == value & 0x0F and not controlword & Cw.FAULT_RESET:
            return cmd
    return None


# -- statusword (0x6041) and states ------------------------------------------------


class Sw(IntEnum):
    """Statusword bits."""

    READY_TO_SWITCH_ON = 1 << 0
    SWITCHED_ON = 1 << 1
    OPERATION_ENABLED = 1 << 2
    FAULT = 1 << 3
    VOLTAGE_ENABLED = 1 << 4
    QUICK_STOP = 1 << 5  # active low: 0 while a quick stop is active
    SWITCH_ON_DISABLED = 1 << 6
    WARNING = 1 << 7
    REMOTE = 1 << 9
    TARGET_REACHED = 1 << 10  # PV: velocity in 0x606D; PP: position in 0x6067, at rest
    INTERNAL_LIMIT = 1 << 11
    SPEED_ZERO = 1 << 12  # profile velocity mode: |velocity| <= 0x606F for 0x6070 ms
    SET_POINT_ACKNOWLEDGE = 1 << 12  # profile position mode: the same bit, another meaning
    MAX_SLIPPAGE = 1 << 13


class State(Enum):
    """402 states with their statusword (mask, value)."""

    NOT_READY_TO_SWITCH_ON = (0x4F, 0x00)
    SWITCH_ON_DISABLED = (0x4F, 0x40)
    READY_TO_SWITCH_ON = (0x6F, 0x21)
    SWITCHED_ON = (0x6F, 0x23)
    OPERATION_ENABLED = (0x6F, 0x27)
    QUICK_STOP_ACTIVE = (0x6F, 0x07)
    FAULT_REACTION_ACTIVE = (0x4F, 0x0F)
    FAULT = (0x4F, 0x08)

    @property
    def bits(self) -> int:
        """The statusword bits this state shows."""
        return self.value[1]

    @property
    def label(self) -> str:
        return self.name.replace("_", " ").lower()

    @property
    def power_stage_on(self) -> bool:
        """The motor is driven (it can move under the drive's control) in these states."""
        return self in POWER_ON_STATES


POWER_ON_STATES = frozenset({State.OPERATION_ENABLED, State.QUICK_STOP_ACTIVE,
                             State.FAULT_REACTION_ACTIVE})


def decode_state(statusword: int) -> State:
    """The 402 state a statusword shows (checked in an order where masks cannot collide)."""
    for state in State:
        mask, value = state.value
        if statusword & mask == value:
            return state
    raise ValueError(f"statusword 0x{statusword:04X} shows no CiA 402 state")


@dataclass(frozen=True)
class Transition:
    """One arc of the 402 state machine that a controlword command drives."""

    number: int  # CiA 402's transition number
    source: State
    command: Command
    target: State


#: the controller-driven arcs (internal ones: 0, 1 power-up, 13, 14 fault, and the end
#: of a quick stop, are the drive's own and live in the twin)
TRANSITIONS: tuple[Transition, ...] = (
    Transition(2, State.SWITCH_ON_DISABLED, Command.SHUTDOWN, State.READY_TO_SWITCH_ON),
    Transition(3, State.READY_TO_SWITCH_ON, Command.SWITCH_ON, State.SWITCHED_ON),
    # 3 + 4 in one step, as CiA 402 allows ("switch on + enable operation")
    Transition(34, State.READY_TO_SWITCH_ON, Command.ENABLE_OPERATION, State.OPERATION_ENABLED),
    Transition(4, State.SWITCHED_ON, Command.ENABLE_OPERATION, State.OPERATION_ENABLED),
    Transition(5, State.OPERATION_ENABLED, Command.SWITCH_ON, State.SWITCHED_ON),
    Transition(6, State.SWITCHED_ON, Command.SHUTDOWN, State.READY_TO_SWITCH_ON),
    Transition(7, State.READY_TO_SWITCH_ON, Command.DISABLE_VOLTAGE, State.SWITCH_ON_DISABLED),
    Transition(7, State.READY_TO_SWITCH_ON, Command.QUICK_STOP, State.SWITCH_ON_DISABLED),
    Transition(8, State.OPERATION_ENABLED, Command.SHUTDOWN, State.READY_TO_SWITCH_ON),
    Transition(9, State.OPERATION_ENABLED, Command.DISABLE_VOLTAGE, State.SWITCH_ON_DISABLED),
    Transition(10, State.SWITCHED_ON, Command.DISABLE_VOLTAGE, State.SWITCH_ON_DISABLED),
    Transition(10, State.SWITCHED_ON, Command.QUICK_STOP, State.SWITCH_ON_DISABLED),
    Transition(11, State.OPERATION_ENABLED, Command.QUICK_STOP, State.QUICK_STOP_ACTIVE),
    Transition(12, State.QUICK_STOP_ACTIVE, Command.DISABLE_VOLTAGE, State.SWITCH_ON_DISABLED),
    Transition(15, State.FAULT, Command.FAULT_RESET, State.SWITCH_ON_DISABLED),
    Transition(16, State.QUICK_STOP_ACTIVE, Command.ENABLE_OPERATION, State.OPERATION_ENABLED),
)


#: 0x605A codes that stay in Quick stop active after standstill: only these allow
#: transition 16 back to Operation enabled (CiA 402-2 / IEC 61800-7-201, quick stop
#: option code; restated in the Nanotec PD4-E manual, 0x605A, and Synapticon's)
QUICK_STOP_STAYS = frozenset({5, 6, 7, 8})


def transition(source: State, command: Command,
               quick_stop_option: int | None = None) -> Transition | None:
    """The arc a command takes from a state, or None when the command does nothing there.

    Transition 16 (Quick stop active -> Operation enabled) exists only for quick stop
    option codes 5-8; with `quick_stop_option` unknown (None) it is not offered."""
    for t in TRANSITIONS:
        if t.source is source and t.command is command:
            if t.number == 16 and quick_stop_option not in QUICK_STOP_STAYS:
                return None
            return t
    return None


#: arcs the driver's path search avoids: it never lets the motor coast, never quick-stops
#: to get somewhere, and goes Ready -> Switched on -> Enabled one step at a time
_PATH_AVOIDS = frozenset({9, 12, 34, 7, 10, 11})


def path(source: State, target: State, quick_stop_option: int | None = None) -> list[Command]:
    """Commands that take the drive from `source` to `target` (shortest, by TRANSITIONS);
    transition 16 only where `quick_stop_option` allows it (QUICK_STOP_STAYS)."""
    if source is target:
        return []
    arcs = [t for t in TRANSITIONS
            if (t.number not in _PATH_AVOIDS
                or (target is State.SWITCH_ON_DISABLED and t.number in (7, 10, 12)))
            and (t.number != 16 or quick_stop_option in QUICK_STOP_STAYS)]
    seen = {source}
    queue: deque[tuple[State, list[Command]]] = deque([(source, [])])
    while queue:
        state, cmds = queue.popleft()
        for t in arcs:
            if t.source is state and t.target not in seen:
                if t.target is target:
                    return [*cmds, t.command]
                seen.add(t.target)
                queue.append((t.target, [*cmds, t.command]))
    raise ValueError(f"no controlword path from {source.label} to {target.label}")


# -- option codes (what the drive does on its own) --------------------------------


class Ramp(Enum):
    """Which deceleration a stop uses."""

    PROFILE = "profile deceleration 0x6084"
    QUICK_STOP = "quick stop deceleration 0x6085"
    CURRENT_LIMIT = "at the current limit (the twin: max deceleration 0x60C6)"
    VOLTAGE_LIMIT = "at the voltage limit (the twin: max deceleration 0x60C6)"
    COAST = "none (coast)"


# Option codes, CiA 402-2 (IEC 61800-7-201) 0x605A..0x605E, as restated in the Nanotec
# PD4-E technical manual (object descriptions 605Ah-605Eh) and Synapticon's object
# reference. Values not listed are reserved (or manufacturer specific, < 0): a drive
# refuses them with SDO abort 0x06090030 (value range of parameter exceeded, CiA 301).

#: 0x605A quick stop option code -> (ramp, state after standstill)
QUICK_STOP_OPTIONS: dict[int, tuple[Ramp, State]] = {
    0: (Ramp.COAST, State.SWITCH_ON_DISABLED),
    1: (Ramp.PROFILE, State.SWITCH_ON_DISABLED),
    2: (Ramp.QUICK_STOP, State.SWITCH_ON_DISABLED),
    3: (Ramp.CURRENT_LIMIT, State.SWITCH_ON_DISABLED),
    4: (Ramp.VOLTAGE_LIMIT, State.SWITCH_ON_DISABLED),
    5: (Ramp.PROFILE, State.QUICK_STOP_ACTIVE),
    6: (Ramp.QUICK_STOP, State.QUICK_STOP_ACTIVE),
    7: (Ramp.CURRENT_LIMIT, State.QUICK_STOP_ACTIVE),
    8: (Ramp.VOLTAGE_LIMIT, State.QUICK_STOP_ACTIVE),
}

#: 0x605B shutdown and 0x605C disable-operation option codes -> ramp before the power stage opens
SLOW_DOWN_OPTIONS: dict[int, Ramp] = {0: Ramp.COAST, 1: Ramp.PROFILE}

#: 0x605D halt option code -> ramp (the drive stays in Operation enabled)
HALT_OPTIONS: dict[int, Ramp] = {1: Ramp.PROFILE, 2: Ramp.QUICK_STOP, 3: Ramp.CURRENT_LIMIT,
                                 4: Ramp.VOLTAGE_LIMIT}

#: 0x605E fault reaction option code -> ramp before the Fault state
FAULT_REACTION_OPTIONS: dict[int, Ramp] = {0: Ramp.COAST, 1: Ramp.PROFILE, 2: Ramp.QUICK_STOP,
                                           3: Ramp.CURRENT_LIMIT, 4: Ramp.VOLTAGE_LIMIT}


class AbortReaction(Enum):
    """0x6007 abort connection option code: what a lost controller heartbeat (or NMT
    Stopped / a reset while enabled) does. 4..32767 reserved."""

    NONE = 0
    FAULT = 1
    DISABLE_VOLTAGE = 2
    QUICK_STOP = 3


#: option-code object -> the values it takes (anything else: abort 0x06090030)
OPTION_CODES: dict[int, frozenset[int]] = {
    0x6007: frozenset(r.value for r in AbortReaction),
    0x605A: frozenset(QUICK_STOP_OPTIONS),
    0x605B: frozenset(SLOW_DOWN_OPTIONS),
    0x605C: frozenset(SLOW_DOWN_OPTIONS),
    0x605D: frozenset(HALT_OPTIONS),
    0x605E: frozenset(FAULT_REACTION_OPTIONS),
}


# -- modes of operation -----------------------------------------------------------


@dataclass(frozen=True)
class Mode:
    """One mode of operation: its 0x6060 code and the object that carries its set-point.

    `setpoint_on_write`: a write of the target starts the motion (PV); otherwise the
    rising edge of controlword bit 4 does (PP). `speed_zero_bit`: the statusword bit
    that shows standstill in this mode, or None where bit 12 means something else (PP:
    set-point acknowledge) and standstill is read from velocity actual.
    """

    code: int
    name: str
    target: Od
    setpoint_on_write: bool = True
    speed_zero_bit: int | None = Sw.SPEED_ZERO

    @property
    def supported_bit(self) -> int:
        """Its bit in 0x6502 supported drive modes (bit n-1 for the standard modes n >= 1)."""
        return 1 << (self.code - 1)


PROFILE_VELOCITY = Mode(3, "profile velocity", Od.TARGET_VELOCITY)
PROFILE_POSITION = Mode(1, "profile position", Od.TARGET_POSITION,
                        setpoint_on_write=False, speed_zero_bit=None)

#: every mode the project knows, by 0x6060 code (another mode is one more entry here and
#: one more handler in the twin)
MODES: dict[int, Mode] = {m.code: m for m in (PROFILE_VELOCITY, PROFILE_POSITION)}


# -- emergency codes (CiA 301 / CiA 402) ------------------------------------------


class ErrorRegister(IntEnum):
    """0x1001 error register bits (sent in every EMCY)."""

    GENERIC = 1 << 0
    CURRENT = 1 << 1
    VOLTAGE = 1 << 2
    TEMPERATURE = 1 << 3
    COMMUNICATION = 1 << 4
    PROFILE = 1 << 5
    MANUFACTURER = 1 << 7


@dataclass(frozen=True)
class DriveErrorCode:
    """An EMCY error code, what it means and which error-register bits it sets."""

    code: int
    description: str
    register: int = ErrorRegister.GENERIC

    def __str__(self) -> str:
        return f"0x{self.code:04X} {self.description}"


FOLLOWING_ERROR = DriveErrorCode(0x8611, "following error",
                                 ErrorRegister.GENERIC | ErrorRegister.PROFILE)
OVER_TEMPERATURE = DriveErrorCode(0x4310, "excess temperature, drive",
                                  ErrorRegister.GENERIC | ErrorRegister.TEMPERATURE)
OVER_CURRENT = DriveErrorCode(0x2310, "continuous over-current",
                              ErrorRegister.GENERIC | ErrorRegister.CURRENT)
HEARTBEAT_LOST = DriveErrorCode(0x8130, "life guard or heartbeat error",
                                ErrorRegister.GENERIC | ErrorRegister.COMMUNICATION)

ERROR_CODES: dict[int, DriveErrorCode] = {
    e.code: e for e in (FOLLOWING_ERROR, OVER_TEMPERATURE, OVER_CURRENT, HEARTBEAT_LOST)}

#: CiA 301 EMCY error code classes (high byte / nibble), for codes this table does not name
_ERROR_CLASSES = ((0xFF00, 0x1000, "generic error"), (0xF000, 0x2000, "current"),
                  (0xF000, 0x3000, "voltage"), (0xF000, 0x4000, "temperature"),
                  (0xFF00, 0x5000, "device hardware"), (0xF000, 0x6000, "device software"),
                  (0xFF00, 0x7000, "additional modules"), (0xF000, 0x8000, "monitoring"),
                  (0xFF00, 0x9000, "external error"), (0xFF00, 0xF000, "additional functions"),
                  (0xFF00, 0xFF00, "device specific"))


def describe_error(code: int) -> str:
    """What an EMCY code means, from the table or else its CiA 301 class."""
    if code in ERROR_CODES:
        return ERROR_CODES[code].description
    for mask, value, text in _ERROR_CLASSES:
        if code & mask == value:
            return text
    return "unknown error"


# -- units ------------------------------------------------------------------------

INT32_MAX = 2**31 - 1
UINT32_MAX = 2**32 - 1



def _within(units: int, limit: float | None, to_deg: Callable[[int], float]) -> int:
    """Step a rounded command one unit toward zero if it lands beyond `limit` (deg)."""
    if limit is not None and abs(to_deg(units)) > limit and units != 0:
        units -= 1 if units > 0 else -1
    return units

@dataclass(frozen=True)
class DriveUnits:
    """Drive units <-> deg, deg/s, deg/s^2: the one place the conversion lives.

    Position in encoder counts (0x608F), velocity in `velocity_unit_counts_per_s`
    counts/s per unit, acceleration in `accel_unit_counts_per_s2` counts/s^2 per unit.
    Conversions to the drive round to the nearest unit; the driver reports the
    rounded value it sent.
    """

    counts_per_rev: int = DEFAULT_COUNTS_PER_REV
    velocity_unit_counts_per_s: float = 1.0e-3
    accel_unit_counts_per_s2: float = 1.0

    def __post_init__(self) -> None:
        if self.counts_per_rev <= 0:
            raise ValueError(f"counts_per_rev must be > 0, got {self.counts_per_rev}")
        if not self.velocity_unit_counts_per_s > 0:
            raise ValueError("velocity_unit_counts_per_s must be > 0, "
                             f"got {self.velocity_unit_counts_per_s}")
        if not self.accel_unit_counts_per_s2 > 0:
            raise ValueError("accel_unit_counts_per_s2 must be > 0, "
                             f"got {self.accel_unit_counts_per_s2}")

    @property
    def deg_per_count(self) -> float:
        return 360.0 / self.counts_per_rev

    def deg_to_counts(self, deg: float) -> int:
        return round(deg / self.deg_per_count)

    def counts_to_deg(self, counts: int) -> float:
        return counts * self.deg_per_count

    def dps_to_velocity(self, dps: float, limit_dps: float | None = None) -> int:
        """The nearest drive unit; with `limit_dps`, never beyond it in magnitude (a
        coarse unit, 1 rpm = 6 deg/s, would otherwise round 400 deg/s up to 402)."""
        units = round(dps / (self.deg_per_count * self.velocity_unit_counts_per_s))
        return _within(units, limit_dps, self.velocity_to_dps)

    def velocity_to_dps(self, units: int) -> float:
        return units * self.deg_per_count * self.velocity_unit_counts_per_s

    def dps2_to_accel(self, dps2: float, limit_dps2: float | None = None) -> int:
        """The nearest drive unit; with `limit_dps2`, never beyond it in magnitude."""
        units = round(dps2 / (self.deg_per_count * self.accel_unit_counts_per_s2))
        return _within(units, limit_dps2, self.accel_to_dps2)

    def accel_to_dps2(self, units: int) -> float:
        return units * self.deg_per_count * self.accel_unit_counts_per_s2

    @property
    def max_velocity_dps(self) -> float:
        """The largest rate 0x60FF (INTEGER32) can carry in these units."""
        return self.velocity_to_dps(INT32_MAX)

    @property
    def max_accel_dps2(self) -> float:
        """The largest acceleration 0x6083 (UNSIGNED32) can carry in these units."""
        return self.accel_to_dps2(UINT32_MAX)


# -- the factor group (CiA 402-2 / IEC 61800-7-201 "factor group", 0x608F..0x60AA) ----
#
# SI unit objects (0x60A9 velocity, 0x60AA acceleration) are four bytes, high to low:
# the power-of-ten prefix (signed), the numerator's unit code, then the denominator's
# time code(s). Sources: Synapticon SOMANET object 0x60A9 (1 RPM = 0x00B44700, 0.001 RPM
# = 0xFDB44700); Nanotec PD4-E technical manual 5.3.1 "Units" (revolution 0xB4, degree
# 0x41, radian 0x10). Unverified against CiA 402-2 itself (not public): the increment
# code 0xB5, the second 0x03, and 0x60AA's layout (a second time byte for s^2).

SI_UNIT_DEG = {0xB4: 360.0, 0x41: 1.0, 0x10: 180.0 / math.pi}  # per numerator unit
SI_UNIT_INCREMENT = 0xB5
SI_TIME_S = {0x03: 1.0, 0x47: 60.0, 0x48: 3600.0}  # second, minute, hour


def si_unit(prefix: int, unit: int, time1: int, time2: int = 0) -> int:
    """Encode an SI unit object: `si_unit(-3, 0xB5, 0x03)` = 0.001 inc/s = 0xFDB50300."""
    return ((prefix & 0xFF) << 24) | (unit << 16) | (time1 << 8) | time2


def si_unit_text(code: int) -> str:
    prefix = ((code >> 24) & 0xFF) - 256 * (((code >> 24) & 0xFF) >= 128)
    names = {0xB4: "rev", 0x41: "deg", 0x10: "rad", SI_UNIT_INCREMENT: "inc"}
    times = {0x03: "s", 0x47: "min", 0x48: "h", 0: ""}
    unit, t1, t2 = (code >> 16) & 0xFF, (code >> 8) & 0xFF, code & 0xFF
    den = "/".join(times.get(t, f"0x{t:02X}") for t in (t1, t2) if t)
    scale = "" if prefix == 0 else f"1e{prefix} "
    return f"{scale}{names.get(unit, f'0x{unit:02X}')}/{den} (0x{code:08X})"


def si_unit_deg(code: int, counts_per_rev: float, *, accel: bool) -> float:
    """deg/s (or deg/s^2 with `accel`) of one drive unit of an SI unit object."""
    b = code.to_bytes(4, "big")
    prefix = int.from_bytes(b[:1], "big", signed=True)
    unit, t1, t2 = b[1], b[2], b[3]
    if unit == SI_UNIT_INCREMENT:
        per_unit = 360.0 / counts_per_rev
    elif unit in SI_UNIT_DEG:
        per_unit = SI_UNIT_DEG[unit]
    else:
        raise ValueError(f"SI unit 0x{code:08X}: numerator code 0x{unit:02X} unknown "
                         f"(know revolution 0xB4, degree 0x41, radian 0x10, increment 0xB5)")
    times = (t1, t2) if accel else (t1,)
    if (not accel and t2) or any(t not in SI_TIME_S for t in times):
        raise ValueError(f"SI unit 0x{code:08X}: time code(s) not of a "
                         f"{'per-second-squared' if accel else 'per-second'} unit")
    per_s = math.prod(SI_TIME_S[t] for t in times)
    return per_unit * 10.0 ** prefix / per_s


@dataclass(frozen=True)
class UnitFactors:
    """The drive's factor group as read back: what one drive unit is at the table axis."""

    encoder_increments: int
    motor_revolutions: int
    gear_motor_revs: int
    gear_shaft_revs: int
    velocity_si: int
    acceleration_si: int
    velocity_factor: tuple[int, int] = (1, 1)
    acceleration_factor: tuple[int, int] = (1, 1)

    @property
    def counts_per_rev(self) -> float:
        """Encoder increments per revolution of the table (shaft), 0x608F and 0x6091."""
        return (self.encoder_increments / self.motor_revolutions
                * self.gear_motor_revs / self.gear_shaft_revs)

    def drive_units(self, apply_factors: bool = False) -> DriveUnits:
        """The conversion to deg, deg/s and deg/s^2 these factors imply.

        0x6096/0x6097 other than 1/1 are refused: how a drive applies them (before or
        after the SI unit) differs between makers, and a guess is a factor error. The
        twin (`apply_factors`) applies them one way: a drive unit is num/div of the SI
        unit (the DSP 402 v2 reading; unverified against CiA 402-2 itself).
        """
        for name, f in (("0x6096 velocity factor", self.velocity_factor),
                        ("0x6097 acceleration factor", self.acceleration_factor)):
            if f[1] == 0 or f[0] == 0 or (f[0] != f[1] and not apply_factors):
                raise ValueError(f"{name} = {f[0]}/{f[1]}: only 1/1 is supported")
        cpr = self.counts_per_rev
        if cpr != round(cpr) or cpr <= 0:
            raise ValueError(f"0x608F/0x6091 give {cpr:g} increments per table revolution: "
                             "not a whole positive number")
        deg_per_count = 360.0 / cpr
        vf = self.velocity_factor[0] / self.velocity_factor[1]
        af = self.acceleration_factor[0] / self.acceleration_factor[1]
        return DriveUnits(int(round(cpr)),
                          vf * si_unit_deg(self.velocity_si, cpr, accel=False) / deg_per_count,
                          af * si_unit_deg(self.acceleration_si, cpr, accel=True)
                          / deg_per_count)

    def as_record(self) -> dict[str, str]:
        return {"0x608F": f"{self.encoder_increments}/{self.motor_revolutions}",
                "0x6091": f"{self.gear_motor_revs}/{self.gear_shaft_revs}",
                "0x6096": "/".join(map(str, self.velocity_factor)),
                "0x6097": "/".join(map(str, self.acceleration_factor)),
                "0x60A9": si_unit_text(self.velocity_si),
                "0x60AA": si_unit_text(self.acceleration_si)}


#: the SI units the stand file may name for drive.unit_factors (set at connect)
NAMED_SI_UNITS: dict[str, int] = {
    "inc/s": si_unit(0, SI_UNIT_INCREMENT, 0x03), "0.001 inc/s": si_unit(-3, 0xB5, 0x03),
    "rpm": si_unit(0, 0xB4, 0x47), "0.001 rpm": si_unit(-3, 0xB4, 0x47),
    "deg/s": si_unit(0, 0x41, 0x03), "0.001 deg/s": si_unit(-3, 0x41, 0x03),
    "inc/s2": si_unit(0, SI_UNIT_INCREMENT, 0x03, 0x03),
    "rpm/s": si_unit(0, 0xB4, 0x47, 0x03), "deg/s2": si_unit(0, 0x41, 0x03, 0x03),
}


def wrap_int32(value: int) -> int:
    """A count as INTEGER32 carries it (position actual wraps after 2^31 counts)."""
    return (value + 2**31) % 2**32 - 2**31


def unwrap_int32(previous_raw: int, raw: int) -> int:
    """Signed step from one INTEGER32 reading to the next, across a wrap."""
    return wrap_int32(raw - previous_raw)


def is_finite(x: float) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x)
