"""A CiA 402 servo drive on a CAN bus, turning one axis of the simulated stand.

The twin is a canopen LocalNode serving this project's EDS. Its state machine is the
table in drivers/cia402.py; its profile generator is the stand model's own ramp
(`AxisModel.command_rate`), so the FOG and counter twins see exactly the motion the
drive commands. Velocity and position actual values are the model's, sampled on the
stand's virtual clock.

Two time bases meet here, as on a real bench: the CAN side (heartbeats, TPDO event
timers, the heartbeat-consumer watchdog) runs in real time, while everything the
table does (ramps, stops, the velocity window and threshold timers) runs on the
stand's virtual clock.

canopen does not copy a LocalNode's data store into its TPDOs, so a tick thread does
it: every TPDO event timer (10 ms in the EDS) it advances the model, refreshes the
statusword bits that depend on motion, finishes ramps that end in a state change,
checks the watchdog, and transmits the TPDOs.

The twin is built in layers, each a module of its own, each reading only the ones below:
the object dictionary and its units (sims/drive_objects.py), the motion model
(sims/drive_motion.py), the CiA 402 state machine (sims/drive_state_machine.py), the
CANopen node: NMT, SDO, PDOs, SYNC, heartbeats (sims/drive_can.py); this module adds
the life cycle and the tick.

On the co-simulation clock (sims/clock.py SteppedClock) the ticks are the clock's events
instead, on a grid of stand time: every event timer while anything moves or changes
(a ramp, a state change, `ACTIVE_S` after any write from the controller, until target
reached; but no faster than `FINE_TICK_S`), every `STEADY_TICK_S` once the table turns
steadily (the TPDOs then carry
what the last one did, to within the noise, and 100 a second over a 29-hour ladder would
cost more than the measurement). The controller's consumption of the TPDOs is counted on
the channel `can_channel_name(channel, node)`, so each reading is stamped at the stand
time of its tick. The thread then only keeps the heartbeat watchdog, in real time.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from pathlib import Path

import canopen
from canopen.objectdictionary import ODArray, ODVariable

from drivers.cia402 import (
    COB_SYNC,
    DEFAULT_EDS_PATH,
    INT32_MAX,
    MODES,
    UINT32_MAX,
    Od,
    State,
    UnitFactors,
    wrap_int32,
)
from drivers.clock import can_channel_name
from drivers.drive_settings import DriveSettings
from sims.clock import SteppedClock
from sims.drive_can import NMT_STOPPED, DriveCanNode, WatchdogTrip, _DriveNmt
from sims.drive_objects import LIVE_OBJECTS, UINT16_MAX, pdo_maps, si_unit_code
from sims.drive_truth import DriveTruth
from sims.stand import SimulatedStand

__all__ = ["DriveTwin", "WatchdogTrip"]

log = logging.getLogger(__name__)

#: co-simulation: stand seconds of ticks at the event timer after any controller write
ACTIVE_S = 3.0
#: co-simulation: stand seconds between ticks while the table turns steadily
STEADY_TICK_S = 30.0
#: co-simulation: the shortest stand time between ticks (the event timer's 10 ms would
#: make five steps of the clock for each one that matters to a settle or a ramp)
FINE_TICK_S = 0.05


class DriveTwin(DriveCanNode):
    """The drive of `stand.axes[axis]` as CANopen node `node_id` on `interface:channel`."""

    def __init__(self, stand: SimulatedStand, axis: str, settings: DriveSettings,
                 truth: DriveTruth | None = None) -> None:
        """`settings`: the stand's drive block (its bus, node ids, encoder), as the driver
        takes it; `truth`: the drive's own power-on configuration."""
        t = truth or DriveTruth()
        node_id = settings.node_id
        if not 1 <= node_id <= 127:
            raise ValueError(f"drive twin node_id must be 1..127, got {node_id}")
        self.settings = settings
        self.truth = t
        interface, channel = settings.interface, settings.channel
        counts_per_rev, gear_ratio = settings.counts_per_rev, t.gear_ratio
        servo_tolerance_dps, standstill_dps = t.servo_tolerance_dps, t.standstill_dps
        max_rate_dps, pp_velocity_dps = t.max_rate_dps, t.pp_velocity_dps
        self.stand = stand
        self.axis = axis
        self.model = stand.axis(axis)
        self.clock = stand.clock
        self.interface = interface
        self.channel = channel
        #: more python-can bus arguments (a real bus interface's own)
        self.bus_options = dict(settings.bus_options)
        self.node_id = node_id
        self._stepped = bool(getattr(self.clock, "stepped", False))
        self._leave: Callable[[], None] | None = None
        self._busy_until_s = 0.0
        self._can_name = can_channel_name(channel, node_id)
        self.eds_path = Path(settings.eds or DEFAULT_EDS_PATH)
        # the factor group (CiA 402 0x608F, 0x6091, 0x60A9, 0x60AA): the twin's units
        # follow from its own factor objects, as a real drive's do, and change when the
        # controller writes 0x60A9/0x60AA (outside Operation enabled)
        motor_revs = 1
        self.factors = UnitFactors(counts_per_rev * gear_ratio[1] // gear_ratio[0]
                                   if counts_per_rev * gear_ratio[1] % gear_ratio[0] == 0
                                   else counts_per_rev, motor_revs, gear_ratio[0],
                                   gear_ratio[1], si_unit_code(t.velocity_unit),
                                   si_unit_code(t.acceleration_unit))
        self.units = self.factors.drive_units()
        self._factors0 = self.factors
        self._sync_count = 0
        self.coast_decel_dps2 = float(t.coast_decel_dps2)
        self._tpdo_event_timer_ms = t.tpdo_event_timer_ms
        #: unit-dependent objects as deg-based values, refitted when the units change
        self._deg_values = {
            "velocity": {(Od.VELOCITY_WINDOW, 0): ("servo_tolerance_dps", servo_tolerance_dps,
                                                   UINT16_MAX),
                         (Od.VELOCITY_THRESHOLD, 0): ("standstill_dps", standstill_dps,
                                                      UINT16_MAX),
                         (Od.MAX_PROFILE_VELOCITY, 0): ("max_rate_dps", max_rate_dps,
                                                        UINT32_MAX),
                         (Od.PROFILE_VELOCITY_PP, 0): ("pp_velocity_dps", pp_velocity_dps,
                                                       UINT32_MAX)},
            "accel": {(Od.MAX_ACCELERATION, 0): ("max_accel_dps2", t.max_accel_dps2,
                                                   UINT32_MAX),
                      (Od.MAX_DECELERATION, 0): ("max_decel_dps2", t.max_decel_dps2,
                                                 UINT32_MAX),
                      (Od.PROFILE_ACCELERATION, 0): ("profile_accel_dps2",
                                                     t.profile_accel_dps2, UINT32_MAX),
                      (Od.PROFILE_DECELERATION, 0): ("profile_accel_dps2",
                                                     t.profile_accel_dps2, UINT32_MAX),
                      (Od.QUICK_STOP_DECELERATION, 0): ("quick_stop_decel_dps2",
                                                        t.quick_stop_decel_dps2, UINT32_MAX)},
        }
        self._initial = self._power_on_values(t.position_window_deg,
                                              settings.controller_node_id, t.watchdog_s,
                                              t.serial_number)
        if self._initial[(Od.MAX_PROFILE_VELOCITY, 0)] > INT32_MAX:
            raise ValueError(f"max_rate_dps = {max_rate_dps} deg/s does not fit 0x60FF "
                             f"(INTEGER32) in these velocity units")
        self._lock = threading.RLock()
        self._init_state_machine()
        self._init_motion()
        self._init_can_node()
        self._initial[(Od.SUPPORTED_DRIVE_MODES, 0)] = sum(
            MODES[code].supported_bit for code in self._mode_handlers)

    # -- life cycle ---------------------------------------------------------------
    def start(self) -> DriveTwin:
        """Join the bus, boot (boot-up message, then pre-operational with heartbeats)."""
        if self._network is not None:
            return self
        network = canopen.Network()
        network.NOTIFIER_CYCLE = 0.1  # disconnect() waits up to one cycle
        node = canopen.LocalNode(self.node_id, str(self.eds_path))
        # the twin's own reactions to NMT commands and SDO requests (CiA 301)
        node._write_callbacks.remove(node.nmt.on_write)
        node.nmt = _DriveNmt(self.node_id, node, self)
        node.add_write_callback(node.nmt.on_write)
        serve_sdo = node.sdo.on_request
        node.sdo.on_request = lambda can_id, data, ts: (  # type: ignore[method-assign]
            None if node.nmt._state == NMT_STOPPED else serve_sdo(can_id, data, ts))
        # the EDS declares 0x1016:1; a twin configured otherwise says so in its own OD
        consumer_heartbeat = node.object_dictionary[Od.CONSUMER_HEARTBEAT]
        assert isinstance(consumer_heartbeat, ODArray)  # the EDS's 0x1016 (ObjectType 0x8)
        consumer_heartbeat[1].default = self._initial[(Od.CONSUMER_HEARTBEAT, 1)]
        network.add_node(node)
        self._network, self._node = network, node
        self._load_defaults(0x1000, 0xFFFF)
        node.add_read_callback(self._on_read)
        node.add_write_callback(self._on_write)
        network.connect(interface=self.interface, channel=self.channel, **self.bus_options)
        for pdo in pdo_maps(node.rpdo).values():
            pdo.add_callback(self._on_rpdo)
        network.subscribe(COB_SYNC, self._on_sync)
        self._read_pdos()
        self._configure_consumer(self._get(Od.CONSUMER_HEARTBEAT, 1))
        with self._lock:
            self._state = State.SWITCH_ON_DISABLED  # transitions 0 and 1: self-test passed
        self._boot_up()
        self._stop.clear()
        if self._stepped:
            node.add_write_callback(self._note_write)
            self._leave = self._stepped_clock.join(self)
        self._thread = threading.Thread(
            target=self._run_watchdog if self._stepped else self._run,
            name=f"drive-twin-{self.axis}", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Leave the bus (the table keeps whatever ramp it was on)."""
        self._stop.set()
        if self._leave is not None:
            self._leave()
            self._leave = None
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        if self._network is not None:
            try:
                if self._node is not None:
                    self._node.nmt.stop_heartbeat()
                self._network.disconnect()
            finally:
                self._network = None

    def silence_heartbeat(self) -> None:
        """Fault hook: the drive's heartbeat producer dies while its TPDOs go on (the fault
        campaign's "drive heartbeat lost")."""
        if self._node is not None:
            self._node.nmt.stop_heartbeat()

    def settle_after_controller(self, limit_s: float = 15.0) -> None:
        """A real drive outlives the controller that left it: wait (real time, at most
        `limit_s`) until a drive left with its power stage on has let its heartbeat
        watchdog act, so the stand shows what the table would do."""
        # its watchdog time, plus what the twin's own starvation may add (_was_starved)
        deadline = time.monotonic() + min(limit_s, self._hb_time_s + 5.0)
        while self._thread is not None and time.monotonic() < deadline:
            with self._lock:
                if not self._state.power_stage_on or not self._hb_producer:
                    return
            time.sleep(0.02)

    def __enter__(self) -> DriveTwin:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def watchdog_s(self) -> float:
        """The heartbeat-consumer time now configured (0x1016:1), s of real time."""
        with self._lock:
            return self._hb_time_s

    @property
    def servo_tolerance_dps(self) -> float:
        """The velocity window 0x606D, deg/s."""
        return self.units.velocity_to_dps(self._get(Od.VELOCITY_WINDOW))

    # -- the tick -----------------------------------------------------------------------
    def _run(self) -> None:
        next_t = time.monotonic()
        while not self._stop.is_set():
            started = time.monotonic()
            try:
                self._watch(next_t)
                self._tick()
            except Exception:  # noqa: BLE001 - a twin must not die silently mid-test
                log.exception("drive twin %s: tick failed", self.axis)
            # the grid, but no burst of ticks to catch up after a late one
            next_t = max(next_t + self._tick_s, started)
            self._stop.wait(max(0.0, next_t - time.monotonic()))

    # -- the co-simulation (sims/clock.py SteppedClock) ----------------------------------
    @property
    def _stepped_clock(self) -> SteppedClock:
        """The co-simulation's clock: reached only on a stepped stand (self._stepped)."""
        assert isinstance(self.clock, SteppedClock)
        return self.clock

    def next_event_s(self, t_s: float) -> float:
        with self._lock:
            busy = (t_s < self._busy_until_s or self._after_standstill is not None
                    or self._state is State.QUICK_STOP_ACTIVE
                    or (self._state is State.OPERATION_ENABLED and not self._target_reached)
                    or t_s < self.model.profile.settle_time_s() + ACTIVE_S)
        period = max(FINE_TICK_S, self._tick_s) if busy else max(STEADY_TICK_S, self._tick_s)
        return (math.floor(t_s / period + 1e-9) + 1) * period

    def advance(self, t_s: float) -> None:
        try:
            self._tick(t_s)
        except Exception:  # noqa: BLE001 - a twin must not die silently mid-test
            log.exception("drive twin %s: tick failed", self.axis)

    def settled(self, t_s: float, final: bool) -> bool:
        """Every TPDO sent so far consumed by the controller (each stamped at its tick)."""
        return self._stepped_clock.backlog(self._can_name) == 0

    def _note_write(self, index: int, subindex: int, od: ODVariable, data: bytes) -> None:
        self._busy_until_s = self.clock.now() + ACTIVE_S

    def _run_watchdog(self) -> None:
        """Stepped clock: the thread keeps only the heartbeat watchdog (real time), and
        ticks in real time while the clock is paused (the bench opening or closing: the
        stand stands still, but the controller still hears the drive's TPDOs)."""
        next_t = time.monotonic() + self._tick_s
        while not self._stop.wait(max(0.0, next_t - time.monotonic())):
            started = time.monotonic()
            self._watch(next_t)
            if not self.clock.running:
                try:
                    self._tick(self.clock.now(), gate_s=time.monotonic())
                except Exception:  # noqa: BLE001 - a twin must not die silently mid-test
                    log.exception("drive twin %s: tick failed", self.axis)
            next_t = max(next_t + self._tick_s, started)

    def _tick(self, t_stepped: float | None = None, gate_s: float | None = None) -> None:
        node = self._node
        if node is None:
            return
        with self._lock:
            t = self.clock.now() if t_stepped is None else t_stepped
            with self.model.lock:
                self.model.advance_to(t)
                w = self.model.rate_dps
                phi = self.model.angle_deg
            self._velocity_units = self.units.dps_to_velocity(w)
            self._position_counts = wrap_int32(self.units.deg_to_counts(phi))
            self._update_motion_bits(t, w)
            if self._after_standstill is not None and self._standing_still():
                self._state, self._after_standstill = self._after_standstill, None
            if node.nmt.state != "OPERATIONAL":
                return
            now = gate_s if gate_s is not None else \
                time.monotonic() if t_stepped is None else t_stepped
            book = self._tpdo_last_paused if gate_s is not None else self._tpdo_last
            for n, pdo in pdo_maps(node.tpdo).items():
                # CiA 301: types 254/255 send on an event: the event timer's expiry, or,
                # with the timer at 0, a change of the mapped data (nothing at rest)
                period = (pdo.event_timer or 0) / 1000.0
                if not pdo.enabled or (period and now - book.get(n, -1e9) <
                                       period - 0.5 * self._tick_s):
                    continue
                if pdo.trans_type not in (254, 255):
                    continue  # synchronous: sent on SYNC (_on_sync)
                values = [self._live(v.index) if v.index in LIVE_OBJECTS else
                          self._get(v.index, v.subindex) for v in pdo.map]
                if not period and values == self._tpdo_values.get(n):
                    continue
                self._tpdo_values[n] = self._send_tpdo(pdo)
                if self._stepped and len(pdo.map):
                    self._stepped_clock.sent(self._can_name, 1)
                book[n] = now
