"""A stand axis's drive, declared once: the `drive:` block of the stand file.

Each key is a field of `DriveSettings`, with its type, default, bounds, unit
(`Meta.extra["unit"]`) and meaning (`Meta.description`). bench/core/schema.py reads this
declaration for `bench validate` (every problem at its file, line and key),
`bench schema` and docs/configuration.md; the stand loader builds the object with
msgspec, and the driver (drivers/axis.py `Axis(name, settings, ...)`) and the drive
twin (sims/drive_twin.py) take it whole, as python-can's `Bus(**config)` takes its
configuration: a new drive setting is declared here and read where it is used.

It lives in the drivers' layer, the bottom one, so the driver and the twin can import it;
it imports msgspec and the drive's constants, not canopen.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Annotated, Any, Literal, Protocol

from msgspec import Meta, Struct

from drivers.calibration import Calibration
from drivers.cia402 import CONTROLLER_NODE_ID, DEFAULT_COUNTS_PER_REV, NAMED_SI_UNITS

# -- what is physically plausible for a rate table (wider than any real bench) ----------
#: a rate table's fastest axes turn some 10 000 deg/s; its slowest useful rate is around
#: 0.001 deg/s (one turn in 100 h): anything outside is a typing slip, not a bench
RATE_MIN_DPS, RATE_MAX_DPS = 1e-3, 20_000.0
ACCEL_MAX_DPS2 = 100_000.0

#: the controller's heartbeat period, ms, where the stand file states none
DEFAULT_HEARTBEAT_MS = 50
#: the TPDO settings: verified at connect, not written, unless the stand says `set`
DEFAULT_PDO: Literal["set", "verify"] = "verify"
#: the drive's units: its factor group read at connect, unless the stand says what to set
DEFAULT_UNIT_FACTORS = "read"
#: how close a position move must land, deg, where the stand file does not say
DEFAULT_POSITION_TOLERANCE_DEG = 0.01

#: a field's `Meta.extra` key: the loader gives the value when the file leaves the key
#: out (resolved from other keys), so the reference shows no default
GIVEN = "given"

NodeId = Annotated[int, Meta(ge=1, le=127)]


class BusAddress(Protocol):
    """Where a drive sits: its bus's interface and channel, and a server's address."""

    @property
    def interface(self) -> str: ...
    @property
    def channel(self) -> str: ...
    @property
    def host(self) -> str | None: ...
    @property
    def port(self) -> int | None: ...


def bus_name(drive: BusAddress) -> str:
    """A bus's identity: interface and channel, and for a bus behind a server
    (socketcand) the server's host and port, so two servers' `can0` are two buses."""
    where = ""
    if drive.host is not None or drive.port is not None:
        where = f"@{'' if drive.host is None else drive.host}:{'' if drive.port is None else drive.port}"
    return f"{drive.interface}:{drive.channel}{where}"


class DriveSettings(Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """A stand axis's `drive:` block: how to reach the drive and what the axis may do."""

    interface: Annotated[str, Meta(description="python-can interface: socketcan, pcan, "
                                               "kvaser, socketcand, virtual...")]
    channel: Annotated[str, Meta(description="python-can channel, e.g. can0 (socketcand: "
                                             "the bus name the server announces)")]
    host: Annotated[str, Meta(
        description="socketcand: the server's address, e.g. 127.0.0.1 for `bench sim` "
                    "(required with interface socketcand)")] | None = None
    port: Annotated[int, Meta(
        ge=1, le=65535,
        description="socketcand: the server's TCP port (required with interface "
                    "socketcand)")] | None = None
    node_id: Annotated[NodeId, Meta(description="the drive's CANopen node id")]
    controller_node_id: Annotated[NodeId, Meta(
        description="this axis's controller node on the bus, whose heartbeat the drive "
                    "watches (default: highest id free on the bus)",
        extra={GIVEN: True})] = CONTROLLER_NODE_ID
    bitrate: Annotated[int, Meta(
        ge=10_000, le=1_000_000, extra={"unit": "bit/s"},
        description="CAN bit rate, where the interface needs it (socketcan takes the "
                    "link's)")] | None = None
    max_rate_dps: Annotated[float, Meta(
        ge=RATE_MIN_DPS, le=RATE_MAX_DPS, extra={"unit": "deg/s"},
        description="the axis's rate limit: a command above it is refused, never "
                    "clipped")]
    max_accel_dps2: Annotated[float, Meta(
        gt=0, le=ACCEL_MAX_DPS2, extra={"unit": "deg/s^2"},
        description="the axis's acceleration limit (and the ramps' default)")]
    counts_per_rev: Annotated[int, Meta(
        ge=1, description="encoder counts per revolution (position and velocity units of "
                          "the drive)")] = DEFAULT_COUNTS_PER_REV
    heartbeat_ms: Annotated[int, Meta(
        ge=10, le=10_000,
        description="controller heartbeat period; the drive watches it")] \
        = DEFAULT_HEARTBEAT_MS
    watchdog_ms: Annotated[int, Meta(
        ge=20, le=65_535,
        description="drive stops the axis when the controller is silent this "
                    "long")] | None = None
    position_tolerance_deg: Annotated[float, Meta(
        gt=0, extra={"unit": "deg"},
        description="how close a position move must land (profile position)")] \
        = DEFAULT_POSITION_TOLERANCE_DEG
    eds: Annotated[str, Meta(
        description="the drive's EDS file, for canopen's object dictionary")] | None = None
    serial: Annotated[str, Meta(
        description="the instrument's serial number: the key of its check values (bench "
                    "control)")] | None = None
    calibration: Annotated[Calibration, Meta(
        description="the encoder's calibration certificate, if any")] | None = None
    unit_factors: Annotated[str | Mapping[str, str], Meta(
        description="'read' (the drive's factor group 0x608F/0x6091/0x60A9/0x60AA is read "
                    "at connect) or {velocity: rpm|inc/s|0.001 inc/s|..., acceleration: "
                    "rpm/s|inc/s2|...} written at connect and read back; a stand without "
                    "a sim: block must state it")] = DEFAULT_UNIT_FACTORS
    quick_stop_decel_dps2: Annotated[float, Meta(
        gt=0, le=ACCEL_MAX_DPS2, extra={"unit": "deg/s^2"},
        description="the quick stop deceleration written to the drive at connect and read "
                    "back (CiA 402 0x6085, in the drive's acceleration units): how hard a "
                    "quick stop or a lost controller brakes the table (default: the drive's "
                    "own)")] | None = None
    pdo: Annotated[Literal["set", "verify"], Meta(
        description="TPDO transmission type / event timer: verify or set at "
                    "connect")] = DEFAULT_PDO

    def __post_init__(self) -> None:
        """The rules between keys, refused where the file is read (`bench validate`)
        rather than when the axis opens. A message starts with the key it is about
        (bench/core/schema.py places it at that key's line)."""
        if self.watchdog_ms is not None and not 2 * self.heartbeat_ms < self.watchdog_ms:
            raise ValueError(f"watchdog_ms: {self.watchdog_ms} must exceed twice "
                             f"heartbeat_ms = {self.heartbeat_ms}")
        if self.pdo not in ("set", "verify"):
            raise ValueError(f"pdo: {self.pdo!r}: 'set' or 'verify'")
        factors = self.unit_factors
        if isinstance(factors, str):
            if factors != "read":
                raise ValueError(f"unit_factors: {factors!r}: 'read' or a mapping "
                                 "{velocity: ..., acceleration: ...}")
        elif set(factors) - {"velocity", "acceleration"} \
                or any(v not in NAMED_SI_UNITS for v in factors.values()):
            raise ValueError(f"unit_factors: {dict(factors)!r}: keys velocity, acceleration;"
                             f" units one of {', '.join(NAMED_SI_UNITS)}")

    @property
    def bus(self) -> str:
        """The CAN bus this drive is on (axes with the same one share it)."""
        return bus_name(self)

    @property
    def bus_options(self) -> dict[str, Any]:
        """The `can.Bus` arguments besides interface and channel the stand states."""
        return {k: v for k in ("host", "port", "bitrate") if (v := getattr(self, k))}
