"""The drive twin as a CANopen node (CiA 301): NMT, the SDO server's writes, the PDOs,
SYNC and the heartbeat consumer, over canopen's LocalNode.

What a CiA 301 drive does and canopen's LocalNode does not, the twin adds (checked with
canopen's own BaseNode402, tests/test_drive_p402_client.py):
- NMT (CiA 301 7.3.2): Stopped, Reset Node and Reset Communication while the power stage
  is on take the abort-connection reaction 0x6007 (CiA 402); a reset restores its area
  of the OD and ends in a boot-up message and pre-operational; no SDO in Stopped; PDOs
  only in Operational.
- PDOs (CiA 301 7.5.2.35-38): COB-ID bit 31, transmission type (254/255 on event, 1-240
  every n-th SYNC), mapping (changed only while the PDO is not valid, sub-index 0 to 0
  before the entries; mappable objects at their own length, 64 bits at most) in effect as
  written; RPDOs write their objects as an SDO would, a synchronous one (0-240) at the
  next SYNC (CiA 301 7.2.2.3).
- SDO writes: reserved option codes refused (abort 0x06090030); the factor group applied
  when written, whole or not at all (sims/drive_objects.py).
"""

from __future__ import annotations

import contextlib
import logging
import struct
import threading
import time
from dataclasses import dataclass

import canopen
from canopen.nmt import NmtSlave
from canopen.objectdictionary import ODVariable
from canopen.pdo.base import PdoMap
from canopen.sdo import SdoAbortedError

from drivers.cia402 import (
    COB_HEARTBEAT,
    MODES,
    OPTION_CODES,
    AbortReaction,
    Od,
)
from sims.drive_objects import (
    ABORT_DEVICE_STATE,
    ABORT_VALUE_RANGE,
    ABORT_VALUE_TOO_HIGH,
    ABORT_VALUE_TOO_LOW,
    LIVE_OBJECTS,
    integer_value,
    pdo_maps,
)
from sims.drive_state_machine import DriveStateMachine

log = logging.getLogger("sims.drive_twin")

ABORT_NOT_MAPPABLE = 0x06040041
ABORT_PDO_LENGTH = 0x06040042

#: CiA 301 NMT command specifiers and states (as canopen numbers them)
NMT_START, NMT_STOP, NMT_PRE_OPERATIONAL, NMT_RESET_NODE, NMT_RESET_COMM = 1, 2, 128, 129, 130
NMT_STOPPED, NMT_OPERATIONAL, NMT_PRE_OP, NMT_INITIALISING = 4, 5, 127, 0
#: real seconds from an NMT reset to the boot-up message (the drive re-initialising)
RESET_BOOT_S = 0.1
#: CiA 301 PDO communication parameter: COB-ID bit 31 "PDO not valid"
PDO_NOT_VALID = 1 << 31
#: a tick this many periods late means the twin itself was not run (a loaded host)
STARVED_TICKS = 5


@dataclass(frozen=True)
class WatchdogTrip:
    """When the heartbeat-consumer watchdog fired (real monotonic and stand times)."""

    last_heartbeat_real_s: float
    tripped_real_s: float
    tripped_t_s: float
    consumer_time_s: float
    reaction: AbortReaction

    @property
    def silence_s(self) -> float:
        """Real time from the controller's last heartbeat to the trip."""
        return self.tripped_real_s - self.last_heartbeat_real_s


class _DriveNmt(NmtSlave):
    """canopen's NMT slave takes every command as a bare state change: a reset never
    boots up again. The twin acts on each command as CiA 301 (7.3.2) and CiA 402 (0x6007)
    say; see DriveCanNode._on_nmt."""

    def __init__(self, node_id: int, local_node: canopen.LocalNode, twin: DriveCanNode) -> None:
        super().__init__(node_id, local_node)
        self._twin = twin

    def on_command(self, can_id: int, data: bytes, timestamp: float) -> None:
        cmd, node_id = struct.unpack_from("BB", data)
        if node_id in (self.id, 0):
            self._twin._on_nmt(cmd)


class DriveCanNode(DriveStateMachine):
    """The drive's CANopen side: what it hears on the bus and what it sends."""

    _tick_s: float
    _stop: threading.Event

    def _init_can_node(self) -> None:
        """Before the node joins the bus: no PDO sent or pending, no heartbeat heard."""
        # heartbeat consumer (0x1016:1): producer id, time, last reception (monotonic). A
        # real drive receives on its CAN controller whatever its motion task is doing, so
        # the reception takes a lock of its own, never the motion lock a tick holds
        self._hb_lock = threading.Lock()
        self._hb_producer = 0
        self._hb_time_s = 0.0
        self._hb_last: float | None = None
        self.watchdog_trips: list[WatchdogTrip] = []
        self._network: canopen.Network | None = None
        self._node: canopen.LocalNode | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._tick_s = 0.01
        self._tpdo_last: dict[int, float] = {}
        self._tpdo_last_paused: dict[int, float] = {}  # stepped clock paused: real time
        self._tpdo_values: dict[int, list[int]] = {}
        #: synchronous RPDOs received, by communication parameter index: (index, sub,
        #: data) written at the next SYNC (_on_rpdo)
        self._rpdo_pending: dict[int, list[tuple[int, int, bytes]]] = {}

    def _read_pdos(self) -> None:
        """Every PDO's communication and mapping parameters as the OD holds them now."""
        node = self._node
        assert node is not None
        for pdo in pdo_maps(node.tpdo).values():
            pdo.read(from_od=False)
        for pdo in pdo_maps(node.rpdo).values():
            self._reload_rpdo(pdo)
        timers = [m.event_timer for m in pdo_maps(node.tpdo).values() if m.enabled and m.event_timer]
        self._tick_s = min(timers, default=10) / 1000.0
        self._sync_count = 0

    def _boot_up(self) -> None:
        """Initialisation done: boot-up message, then pre-operational on its own, with
        the heartbeat producer (0x1017) started (CiA 301 7.3.2.2)."""
        node = self._node
        assert node is not None
        node.nmt._state = NMT_INITIALISING
        node.nmt.stop_heartbeat()
        node.nmt.send_command(NMT_RESET_NODE)  # canopen sends the boot-up message here
        node.nmt._state = NMT_PRE_OP
        # the boot-up message is the first heartbeat: the next one follows a period later
        # (canopen's producer would send one at once, and a client waiting for the
        # boot-up, NmtMaster.wait_for_bootup, would see that one instead)
        period_ms = self._get(Od.PRODUCER_HEARTBEAT)
        if period_ms:
            timer = threading.Timer(period_ms / 1000.0, self._start_heartbeat, (period_ms,))
            timer.daemon = True
            timer.start()

    def _start_heartbeat(self, period_ms: int) -> None:
        with self._lock:
            node = self._node
            if node is not None and not self._stop.is_set() \
                    and node.nmt._state != NMT_INITIALISING:
                node.nmt.start_heartbeat(period_ms)

    def _boot_up_if_running(self) -> None:
        with self._lock:
            if self._node is not None and self._network is not None \
                    and not self._stop.is_set():
                self._boot_up()

    def _on_nmt(self, cmd: int) -> None:
        """An NMT command from the master. Stopped and the resets, while the power stage
        is on, take the abort-connection reaction 0x6007 (CiA 402); a reset then boots up
        again; SDO is not served in Stopped (CiA 301)."""
        node = self._node
        if node is None:
            return
        with self._lock:
            if cmd != NMT_START:   # out of Operational: no SYNC actuates what waited
                self._rpdo_pending.clear()
            if cmd in (NMT_STOP, NMT_RESET_NODE, NMT_RESET_COMM) \
                    and node.nmt._state != NMT_STOPPED:
                self._abort_connection(f"NMT command {cmd}", emcy=cmd == NMT_STOP)
            if cmd == NMT_START:
                node.nmt._state = NMT_OPERATIONAL
            elif cmd == NMT_STOP:
                node.nmt._state = NMT_STOPPED
            elif cmd == NMT_PRE_OPERATIONAL:
                node.nmt._state = NMT_PRE_OP
            elif cmd in (NMT_RESET_NODE, NMT_RESET_COMM):
                if cmd == NMT_RESET_NODE:  # the application area back to power-on values
                    self._reset_application()
                self._load_defaults(0x1000, 0x1FFF)  # the communication area
                self._read_pdos()
                self._configure_consumer(self._get(Od.CONSUMER_HEARTBEAT, 1))
                node.nmt._state = NMT_INITIALISING
                node.nmt.stop_heartbeat()
                # a drive takes a while to initialise: a client that sends the reset
                # and then waits for the boot-up (canopen's wait_for_bootup) sees it
                timer = threading.Timer(RESET_BOOT_S, self._boot_up_if_running)
                timer.daemon = True
                timer.start()
                return
            else:
                return
            node.nmt.update_heartbeat()

    def _pdo_parameter(self, index: int, sub: int, value: int, data: bytes) -> None:
        """A PDO communication (0x1400/0x1800) or mapping (0x1600/0x1A00) parameter
        written: checked as CiA 301 7.5.2.35-38 says, then in effect at once.

        The mapping (7.5.2.36 RPDO / 7.5.2.38 TPDO mapping parameter) is changed by the
        procedure those sections give: the PDO made not valid (COB-ID bit 31), sub-index 0
        set to 0, the entries written, sub-index 0 set to their count, the PDO made valid
        again. Any sub-index written while the PDO is valid, and an entry written while
        sub-index 0 is not 0, is refused with 0x08000022 ("data cannot be transferred or
        stored to the application because of the present device state"; CiA 301's own
        text was not at hand, and the open stacks differ: CANopenNode answers 0x06010000,
        Lely 0x06090030, so no client can rely on one code; the twin keeps the one it gave
        for the entries already). An entry naming an object that does not exist, is not
        mappable, or with a length other than the object's (0x6041, 16 bits, as 32) is
        refused with 0x06040041 "object cannot be mapped to the PDO" (7.5.2.36 step 3;
        CANopenNode's PDOconfigMap alike); a count whose entries exceed the PDO's 64 bits
        or the entries there are with 0x06040042 (step 4)."""
        node = self._node
        assert node is not None
        tx = index >= 0x1800
        base = 0x1800 if tx else 0x1400
        mapping = (index & 0x0200) != 0
        number = (index - base - (0x200 if mapping else 0)) + 1
        pdo = pdo_maps(node.tpdo if tx else node.rpdo).get(number)
        if pdo is None:
            return
        if not mapping and sub == 1:
            if not value & PDO_NOT_VALID and pdo.enabled and value & 0x7FF != pdo.cob_id:
                raise SdoAbortedError(ABORT_VALUE_RANGE)  # a valid PDO's COB-ID stays
        elif not mapping and sub == 2 and 241 <= value <= 251:
            raise SdoAbortedError(ABORT_VALUE_RANGE)  # reserved transmission types
        elif mapping and pdo.enabled:
            raise SdoAbortedError(ABORT_DEVICE_STATE)  # remap only a disabled PDO
        elif mapping and sub == 0:
            bits = 0
            for n in range(1, value + 1):
                try:
                    entry = self._get(index, n)
                except KeyError as e:        # more entries than the PDO has
                    raise SdoAbortedError(ABORT_PDO_LENGTH) from e
                bits += self._mapped_bits(entry)
            if bits > 64:
                raise SdoAbortedError(ABORT_PDO_LENGTH)
        elif mapping and self._get(index, 0) != 0:
            raise SdoAbortedError(ABORT_DEVICE_STATE)  # sub-index 0 to 0 first
        elif mapping and value:
            self._mapped_bits(value)
        node.data_store.setdefault(index, {})[sub] = data  # stored now, read back below
        if tx:
            pdo.read(from_od=False)
            self._tpdo_values.pop(number, None)
        else:
            self._reload_rpdo(pdo)

    def _mapped_bits(self, entry: int) -> int:
        """A mapping entry's length, once its object is found mappable with that length
        (abort 0x06040041 otherwise; see _pdo_parameter)."""
        index, sub, bits = entry >> 16, (entry >> 8) & 0xFF, entry & 0xFF
        node = self._node
        assert node is not None
        try:
            obj = node.object_dictionary[index]
            var = obj if isinstance(obj, ODVariable) else obj[sub]
        except KeyError as e:
            raise SdoAbortedError(ABORT_NOT_MAPPABLE) from e
        if (isinstance(obj, ODVariable) and sub != 0) or not var.pdo_mappable \
                or bits != len(var):
            raise SdoAbortedError(ABORT_NOT_MAPPABLE)
        return bits

    def _reload_rpdo(self, pdo: PdoMap) -> None:
        """Read an RPDO's parameters and listen on its (new) COB-ID, if valid (data it
        received for the next SYNC are dropped: its parameters changed)."""
        self._rpdo_pending.pop(pdo.com_record.od.index, None)
        network = self._network
        if network is not None and pdo.cob_id is not None:
            with contextlib.suppress(KeyError, ValueError):
                network.unsubscribe(pdo.cob_id, pdo.on_message)
        pdo.read(from_od=False)
        if network is not None:
            pdo.subscribe()

    def _on_rpdo(self, pdo: PdoMap) -> None:
        """An RPDO received (only when operational): its objects written as an SDO write
        would. Asynchronous (transmission type 254/255) at once; synchronous (0-240) at
        the next SYNC: CiA 301 7.2.2.3 (PDO transmission types) and 0x1400 sub 2, a
        synchronous RPDO's data are actuated with the next SYNC received; the newest
        received before it wins (Lely's rpdo.c keeps the frame "to be processed after the
        next SYNC object" the same way). Issue 41: the twin applied every RPDO at once."""
        node = self._node
        if node is None or node.nmt._state != NMT_OPERATIONAL:
            return
        writes = [(var.index, var.subindex, bytes(var.get_data())) for var in pdo.map]
        tt = pdo.trans_type
        if tt is not None and tt <= 240:
            with self._lock:
                self._rpdo_pending[pdo.com_record.od.index] = writes
            return
        self._apply_rpdo(writes)

    def _apply_rpdo(self, writes: list[tuple[int, int, bytes]]) -> None:
        node = self._node
        assert node is not None
        for index, sub, data in writes:
            with contextlib.suppress(SdoAbortedError):
                node.set_data(index, sub, data)

    def _on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:
        """SYNC: the synchronous RPDOs received since the last one actuated, then the
        synchronous TPDOs (type 0: acyclic, 1-240: every n-th SYNC) sent (CANopenNode's
        order: CO_process_SYNC, CO_process_RPDO, CO_process_TPDO)."""
        node = self._node
        if node is None or node.nmt._state != NMT_OPERATIONAL:
            return
        with self._lock:
            pending = [self._rpdo_pending.pop(i) for i in sorted(self._rpdo_pending)]
            for writes in pending:
                self._apply_rpdo(writes)
            self._sync_count += 1
            for pdo in pdo_maps(node.tpdo).values():
                tt = pdo.trans_type
                if pdo.enabled and tt is not None and 1 <= tt <= 240 \
                        and self._sync_count % tt == 0:
                    self._send_tpdo(pdo)

    def _send_tpdo(self, pdo: PdoMap) -> list[int]:
        values = [self._live(v.index) if v.index in LIVE_OBJECTS else self._get(v.index, v.subindex)
                  for v in pdo.map]
        for var, value in zip(pdo.map, values, strict=True):
            var.raw = value
        pdo.transmit()
        return values

    def _on_read(self, index: int, subindex: int, od: ODVariable) -> int | None:
        if index not in LIVE_OBJECTS:
            return None
        with self._lock:
            return self._live(index)

    def _on_write(self, index: int, subindex: int, od: ODVariable, data: bytes) -> None:
        """SDO writes from the controller (runs in the CAN receive thread)."""
        value = integer_value(od, data)
        with self._lock:
            if index == Od.CONTROLWORD:
                self._on_controlword(value)
            elif index == Od.MODES_OF_OPERATION:
                if value != 0 and value not in self._mode_handlers:
                    raise SdoAbortedError(ABORT_VALUE_RANGE)
                changed, self._mode = value != self._mode, value
                if changed and value:  # the new mode takes over from its own set-point
                    self._mode_handlers[value]()
            elif index == Od.TARGET_VELOCITY:
                if abs(value) > self._get(Od.MAX_PROFILE_VELOCITY):
                    raise SdoAbortedError(ABORT_VALUE_TOO_HIGH)
            elif index in (Od.PROFILE_ACCELERATION, Od.PROFILE_DECELERATION,
                           Od.QUICK_STOP_DECELERATION):
                limit = self._get(Od.MAX_ACCELERATION if index == Od.PROFILE_ACCELERATION
                                  else Od.MAX_DECELERATION)
                if value <= 0:
                    raise SdoAbortedError(ABORT_VALUE_TOO_LOW)
                if value > limit:
                    raise SdoAbortedError(ABORT_VALUE_TOO_HIGH)
            elif index == Od.CONSUMER_HEARTBEAT and subindex == 1:
                self._configure_consumer(value)
            elif (index, subindex) in self._FACTOR_FIELDS:
                self._change_units(index, subindex, value)
            elif index in OPTION_CODES:
                if value not in OPTION_CODES[index]:  # reserved or manufacturer specific
                    raise SdoAbortedError(ABORT_VALUE_RANGE)
            elif 0x1400 <= index <= 0x1BFF:
                self._pdo_parameter(index, subindex, value, data)
            mode = MODES.get(self._mode)
            if mode is not None and index == mode.target and mode.setpoint_on_write:
                self._mode_handlers[mode.code](value)  # a new set-point of the active mode

    # -- heartbeat consumer (CiA 301 0x1016) and the abort-connection reaction ----------
    def _configure_consumer(self, entry: int) -> None:
        network = self._network
        old = self._hb_producer
        producer, time_ms = (entry >> 16) & 0xFF, entry & 0xFFFF
        if network is not None and old and old != producer:
            network.unsubscribe(COB_HEARTBEAT + old, self._on_controller_heartbeat)
        with self._hb_lock:
            self._hb_producer = producer if time_ms else 0
            self._hb_time_s = time_ms / 1000.0
            self._hb_last = None  # CiA 301: monitoring starts with the next heartbeat received
        if self._hb_producer and network is not None:
            network.subscribe(COB_HEARTBEAT + producer, self._on_controller_heartbeat)

    def _on_controller_heartbeat(self, can_id: int, data: bytearray, timestamp: float) -> None:
        with self._hb_lock:
            self._hb_last = time.monotonic()

    def _watch(self, due_real_s: float) -> None:
        """One look of the heartbeat watchdog, due at `due_real_s` (monotonic): lateness
        is measured once the motion lock is held, so a late wake-up, the last tick's and
        this lock's wait are all forgiven before the controller's silence is judged."""
        with self._lock:
            self._forgive_lateness(due_real_s)
            self._check_watchdog(self.clock.now())

    def _forgive_lateness(self, due_real_s: float) -> None:
        """This thread looks at the watchdog `STARVED_TICKS` periods or more after it was
        due: the host did not run it, or it (or its previous tick) waited that long for a
        lock another thread of this process held (the twin's, the stand's; a loaded
        machine). Either is the twin's own starvation, not the controller's silence: a
        real drive's heartbeat consumer has a timer and a processor of its own."""
        late = time.monotonic() - due_real_s
        if late > STARVED_TICKS * self._tick_s:
            self._was_starved(late)

    def _was_starved(self, late_s: float) -> None:
        """A real drive has a processor of its own; the twin shares the host's with the
        controller. The time the twin itself was not run (a loaded host) is not counted
        as the controller's silence: the controller's heartbeats of that while may still
        sit in the bus queue."""
        with self._hb_lock:
            if self._hb_last is not None:
                self._hb_last = min(self._hb_last + late_s, time.monotonic())

    def _check_watchdog(self, t: float) -> None:
        """Called with the motion lock held, right after `_was_starved` has forgiven the
        twin's own lateness (the thread's wake-up and the previous tick's wait for a lock
        alike), so only the controller's silence trips it."""
        with self._hb_lock:
            last = self._hb_last
            now = time.monotonic()
            if not self._hb_producer or last is None or now - last <= self._hb_time_s:
                return
            self._hb_last = None  # re-armed by the next heartbeat
        reaction = AbortReaction(self._get(Od.ABORT_CONNECTION_OPTION))
        self.watchdog_trips.append(WatchdogTrip(last, now, t, self._hb_time_s, reaction))
        log.warning("drive twin %s: no heartbeat from node %d for %.3f s: %s", self.axis,
                    self._hb_producer, now - last, reaction.name)
        self._abort_connection("heartbeat lost")
