"""One rate-table axis: a CiA 402 servo drive on CANopen, in profile velocity mode (and
profile position mode for a turn to an angle, `move_to`).

The same code drives a real drive and the drive twin (sims/drive_twin.py): it talks
CANopen through the `canopen` package over python-can, and takes the bus from the
stand file (`interface`, `channel`; `virtual` for the twin).

What it does, and why:
- On entering its context: SDO checks that the node is a CiA 402 drive with the
  configured encoder resolution, sets up heartbeats both ways (the drive produces
  every `heartbeat_ms`; the drive's heartbeat consumer 0x1016 watches ours, so a dead
  controller gets its table stopped by the drive itself), NMT start, profile velocity
  mode with zero target, then the 402 state machine to Operation enabled.
- Feedback (velocity actual 0x606C, position actual 0x6064, statusword 0x6041) comes
  by TPDO, stamped on arrival with the bench clock.
- Limits are checked before anything is sent: a rate or acceleration over the
  stand's limit raises `LimitError`; nothing is ever clipped.
- An EMCY from the drive, a boot-up, or a silent drive heartbeat becomes a pending
  `DriveFault`; `check()` (and every method that waits) raises it.
- Leaving the context, by return or by exception, ramps to zero and disables.

Time: heartbeats, SDO and TPDO periods are real time (the CAN side); ramps, holds and
settling are in the clock's seconds, and real-time timeouts are scaled by the slowest
the clock can run (`drivers.clock.min_speed`) with a margin.

Threads: `raw` and the feedback bookkeeping run in canopen's receive thread; the
engine's `raw` callable must be thread-safe (an exception in it is kept and raised by
the next `check()`).

The driver is built in layers, each a module of its own, each reading only the ones
below: the CANopen link (drivers/axis_link.py: SDO, journal, liveness, waits), the
readback (drivers/axis_readback.py: TPDOs, EMCY, heartbeats, settling), the 402 state
machine (drivers/axis_states.py), the motion commands and their limits
(drivers/axis_motion.py), the configuration at connect (drivers/axis_config.py); this
module adds the life cycle. The errors are drivers/axis_errors.py's.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from types import TracebackType
from typing import Any

from drivers.axis_config import AxisConfiguration
from drivers.axis_errors import (
    NOT_STOPPED,
    AxisError,
    AxisTimeout,
    DriveFault,
    DriveUnreachable,
    LimitError,
    ObjectRefused,
    PositionError,
)
from drivers.axis_link import (
    REAL_MARGIN_S,
    STANDSTILL_DPS,
    STATE_TIMEOUT_S,
    STEPPED_POLL_S,
    RawSink,
)
from drivers.axis_readback import Feedback
from drivers.cia402 import (
    DEFAULT_EDS_PATH,
    PROFILE_VELOCITY,
    DriveUnits,
    Mode,
    UnitFactors,
)
from drivers.clock import Clock, can_channel_name, channel_closed
from drivers.drive_settings import DriveSettings
from drivers.waits import MIN_REAL_MARGIN_S

__all__ = ["NOT_STOPPED", "REAL_MARGIN_S", "SDO_TIMEOUT_S", "STANDSTILL_DPS", "STATE_TIMEOUT_S",
           "STEPPED_POLL_S", "Axis", "AxisError", "AxisTimeout", "DriveFault",
           "DriveUnreachable", "Feedback", "LimitError", "ObjectRefused", "PositionError",
           "RawSink"]

log = logging.getLogger(__name__)

#: SDO response timeout, real seconds (canopen's 0.3 s is short on a loaded host)
SDO_TIMEOUT_S = 1.0


class Axis(AxisConfiguration):
    """A table axis driven by a CiA 402 drive in profile velocity mode; a context manager."""

    def __init__(self, name: str, settings: DriveSettings, *, clock: Clock,
                 raw: RawSink | None = None, accel_dps2: float | None = None,
                 feedback_journal_s: float = 0.1, velocity_unit_counts_per_s: float = 1.0e-3,
                 accel_unit_counts_per_s2: float = 1.0) -> None:
        """`settings`: the stand's drive block, whole (a setting is read where it is
        used, from `self.settings`). `accel_dps2`: the ramps' acceleration (default the
        axis's limit). The units per count are the drive's until its factor group is
        read at connect (a drive without one keeps them)."""
        self.name = name
        self.settings = settings
        self.interface = settings.interface
        self.channel = settings.channel
        #: more `can.Bus` arguments: a socketcand server's host and port
        self.bus_options = {k: v for k, v in settings.bus_options.items() if k != "bitrate"}
        self.node_id = int(settings.node_id)
        self.clock = clock
        self.eds_path = Path(settings.eds or DEFAULT_EDS_PATH)
        self.bitrate = settings.bitrate
        self.raw = raw
        #: clock seconds between journaled feedback records (0: every TPDO; 100 Hz of
        #: TPDOs for a 10 h ladder would be millions of lines the analysis never reads)
        self.feedback_journal_s = float(feedback_journal_s)
        self._feedback_journaled_t: float | None = None
        self.units = DriveUnits(int(settings.counts_per_rev), float(velocity_unit_counts_per_s),
                                float(accel_unit_counts_per_s2))
        #: "read" (the drive's factor group is the truth) or {velocity, acceleration}:
        #: SI unit names (cia402.NAMED_SI_UNITS) written at connect and read back
        self.unit_factors_setting = settings.unit_factors
        self.pdo_setting = settings.pdo
        #: the factor group and PDO timing as read back at connect (bench devices, journal)
        self.factors: UnitFactors | None = None
        self.readback: dict[str, Any] = {}
        self.max_rate_dps = float(settings.max_rate_dps)
        self.max_accel_dps2 = float(settings.max_accel_dps2)
        if not settings.position_tolerance_deg > 0:
            raise ValueError(f"axis {name} drive: position_tolerance_deg must be > 0, "
                             f"got {settings.position_tolerance_deg}")
        self.position_tolerance_deg = float(settings.position_tolerance_deg)
        self.heartbeat_ms = int(settings.heartbeat_ms)
        self.watchdog_ms = settings.watchdog_ms
        self.controller_node_id = int(settings.controller_node_id)
        self._check_config(accel_dps2)
        self.accel_dps2 = float(accel_dps2) if accel_dps2 is not None else self.max_accel_dps2
        self.mode: Mode = PROFILE_VELOCITY
        self._init_link()
        self._init_readback()
        self._identity: str | None = None
        self._accel_sent: int | None = None
        self._decel_dps2 = self.accel_dps2
        self._quick_stop_decel_dps2 = self.max_accel_dps2
        self.drive_watchdog_ms: int | None = None
        self.abort_connection_option: int | None = None  # 0x6007, read at connect
        self.quick_stop_option: int | None = None  # 0x605A, read at connect
        self._started = False

    # -- context --------------------------------------------------------------------
    def __enter__(self) -> Axis:
        self.open()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        try:
            self.close()
        except Exception as e:
            if exc is None:
                raise
            log.error("axis %s: stopping after %r failed: %s", self.name, exc, e)
            exc.add_note(f"axis {self.name}: stopping the axis afterwards failed too: {e}")

    def open(self) -> None:
        """Connect, configure, NMT start, enable in profile velocity mode at zero rate."""
        if self.network is not None:
            return
        import canopen
        network = canopen.Network()
        network.NOTIFIER_CYCLE = 0.1  # disconnect() waits up to one cycle
        node = canopen.RemoteNode(self.node_id, str(self.eds_path))
        node.sdo.RESPONSE_TIMEOUT = SDO_TIMEOUT_S
        network.add_node(node)
        node.nmt.add_heartbeat_callback(self._on_heartbeat)
        node.emcy.add_callback(self._on_emcy)
        kwargs: dict[str, Any] = {"interface": self.interface, "channel": self.channel,
                                  **self.bus_options}
        if self.bitrate:
            kwargs["bitrate"] = self.bitrate
        try:
            network.connect(**kwargs)
        except Exception as e:
            where = "".join(f" {k}={v}" for k, v in self.bus_options.items())
            raise AxisError(f"axis {self.name}: cannot open CAN bus {self.interface}:"
                            f"{self.channel}{where}: {e}") from e
        self.network, self.node = network, node
        self._started = False
        try:
            self._configure()
            self.enable()
        except BaseException:
            try:
                if self._started:  # NMT start was sent: the drive may be enabled
                    self.close()
                else:
                    self._leave_bus()
            except Exception as e:  # noqa: BLE001 - the first error is the one to see
                log.error("axis %s: cleanup after a failed open: %s", self.name, e)
            raise

    def close(self) -> None:
        """Ramp to zero, disable, stop our heartbeat, leave the bus. Safe to call twice."""
        if self.network is None:
            return
        errors: list[str] = []
        try:
            silence = self._drive_silence_s()
            if silence is not None:
                raise DriveUnreachable(self.name, silence, self.drive_watchdog_ms,
                                       self.abort_connection_option)
            errors = self.safe_stop()
        finally:
            self._leave_bus()
        if errors:
            raise AxisError(f"axis {self.name}: leaving: " + "; ".join(errors))

    def safe_stop(self, log: Callable[[str], None] | None = None) -> list[str]:
        """The one stop sequence (a run's end, an abort, a failed open): ramp to zero with
        the profile deceleration, else a quick stop; then disable. Returns what failed,
        raises nothing: the caller decides whose error the operator reads first."""
        say = log or (lambda text: None)
        errors: list[str] = []
        try:
            self.stop()
            say(f"  {self.name}: ramped to zero")
        except Exception as e:  # noqa: BLE001 - try the harder stop
            say(f"  {self.name}: ramp to zero failed ({e}); quick stop")
            errors.append(f"ramp to zero: {e}")
            try:
                self.quick_stop()
            except Exception as e2:  # noqa: BLE001
                errors.append(f"quick stop: {e2}")
        try:
            self.disable()
            say(f"  {self.name}: disabled")
        except Exception as e:  # noqa: BLE001
            errors.append(f"disable: {e}")
        return errors

    def _leave_bus(self) -> None:
        network, self.network = self.network, None
        channel_closed(self.clock, can_channel_name(self.channel, self.node_id))
        if self._hb_task is not None:
            try:
                self._hb_task.stop()
            except Exception:  # noqa: BLE001 - the bus shutdown stops it anyway
                pass
            self._hb_task = None
        if network is not None:
            network.disconnect()

    def _heartbeat_limit_s(self) -> float:
        """Real silence after which the drive counts as gone: 4 heartbeats + 0.1 s, and
        never less than the bench's real-time minimum (a loaded controller PC can starve
        our receive thread that long; the drive's own watchdog guards the table)."""
        return max(4 * self.heartbeat_ms / 1000.0 + 0.1, MIN_REAL_MARGIN_S)
