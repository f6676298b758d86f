"""The axis driver's CANopen link (drivers/axis.py): SDO reads and writes whose errors
name the axis and the object, the journal of what was sent and heard, the drive's
liveness (its heartbeat, its EMCY) as a pending fault that `check()` raises, and the
waits for what the drive reports.

The bottom layer of `Axis`: the readback, the 402 state machine, the motion commands
and the configuration above it reach the drive only through it.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:   # canopen is imported when an axis opens (`bench validate` reads constants)
    import canopen
    from canopen.sdo import SdoVariable

from drivers.axis_errors import AxisError, AxisTimeout, DriveFault, ObjectRefused
from drivers.cia402 import HEARTBEAT_LOST, Od
from drivers.clock import Clock, stepped
from drivers.heartbeat import HeartbeatProducer
from drivers.json_types import JsonLike
from drivers.waits import MIN_REAL_MARGIN_S, Deadline

RawSink = Callable[[str, dict[str, JsonLike]], None]

#: real seconds added to every wait scaled from the clock (CAN latency, thread wake-ups,
#: a loaded host): the bench's stated minimum (drivers/waits.py)
REAL_MARGIN_S = MIN_REAL_MARGIN_S
#: on a stepped clock (a co-simulation) waits for readings look this often, stand s
STEPPED_POLL_S = 0.05
#: real seconds to wait for one 402 state change or NMT start (the same minimum)
STATE_TIMEOUT_S = MIN_REAL_MARGIN_S
#: |velocity actual| below which a drive in a mode without a speed-zero bit is at rest
STANDSTILL_DPS = 1e-3


@dataclass(frozen=True)
class _FaultInfo:
    code: int | None
    description: str
    register: int
    t_s: float


class AxisLink:
    """One drive node's CANopen link, and the faults it has reported."""

    name: str
    node_id: int
    interface: str
    channel: str
    clock: Clock
    eds_path: Path
    raw: RawSink | None
    heartbeat_ms: int

    def _init_link(self) -> None:
        """Not on the bus yet: nothing heard, no fault."""
        self.network: canopen.Network | None = None
        self.node: canopen.RemoteNode | None = None
        self._hb_task: HeartbeatProducer | None = None
        self._lock = threading.Condition()
        self._fault: _FaultInfo | None = None
        self._raw_error: BaseException | None = None
        self._drive_hb_last: float | None = None
        self._tpdo_period_s = 0.01

    def check(self) -> None:
        """Raise the pending fault, if any: EMCY, boot-up, silent drive, lost feedback."""
        network = self._require_open()
        network.check()
        now = time.monotonic()
        with self._lock:
            if self._raw_error is not None:
                err, self._raw_error = self._raw_error, None
                raise AxisError(f"axis {self.name}: the raw-data callback failed: {err}") \
                    from err
            last = self._drive_heard_s()
            if (self._fault is None and last is not None
                    and now - last > self._heartbeat_limit_s()):
                self._set_fault(HEARTBEAT_LOST.code,
                                f"no heartbeat from the drive for "
                                f"{now - last:.3f} s (it sends every "
                                f"{self.heartbeat_ms} ms)", 0)
            fault = self._fault
        if fault is not None:
            raise DriveFault(self.name, self.node_id, fault.code, fault.description,
                             fault.register, fault.t_s)

    def _set_fault(self, code: int | None, description: str, register: int) -> None:
        if self._fault is None:  # the first fault is the cause; later ones follow from it
            self._fault = _FaultInfo(code, description, register, self.clock.now())

    def _journal(self, kind: str, **record: JsonLike) -> None:
        if self.raw is None:
            return
        record.setdefault("t_s", self.clock.now())
        try:
            self.raw(kind, record)
        except Exception as e:  # noqa: BLE001 - raised by the next check()
            self._raw_error = self._raw_error or e

    def _require_open(self) -> canopen.Network:
        if self.network is None:
            raise AxisError(f"axis {self.name}: not open (use it as a context manager)")
        return self.network

    def _drive_heard_s(self) -> float | None:
        """When the drive's heartbeat was last heard, or the end of a stall of this host
        (our own heartbeat thread woke late), if later: a drive's heartbeats sent while
        the host starved this process may not have been read yet; that is not silence."""
        if self._drive_hb_last is None:
            return None
        stall_end = self._hb_task.host_stall_end if self._hb_task is not None else 0.0
        return max(self._drive_hb_last, stall_end)

    def _heartbeat_limit_s(self) -> float:
        """Real silence after which the drive counts as gone (`Axis` says how long)."""
        raise NotImplementedError

    def _drive_silence_s(self) -> float | None:
        """How long the drive has not sent a heartbeat, if longer than the limit."""
        with self._lock:
            last = self._drive_heard_s()
        if last is None:
            return None
        silence = time.monotonic() - last
        return silence if silence > self._heartbeat_limit_s() else None

    def _require_alive(self) -> None:
        """Fail fast on a silent drive: an SDO to it would only time out."""
        self._require_open()
        silence = self._drive_silence_s()
        if silence is not None:
            raise DriveFault(self.name, self.node_id, HEARTBEAT_LOST.code,
                             f"no heartbeat from the drive for {silence:.3f} s")

    def _network(self) -> canopen.Network:
        return self._require_open()

    def _node(self) -> canopen.RemoteNode:
        self._require_open()
        assert self.node is not None
        return self.node

    def _sdo_var(self, index: int, sub: int) -> SdoVariable:
        from canopen.sdo import SdoVariable
        obj = self._node().sdo[index]
        return obj if isinstance(obj, SdoVariable) else obj[sub]

    def _describe(self, index: int, sub: int) -> str:
        try:
            name = Od(index).name.lower().replace("_", " ")
        except ValueError:
            name = "object"
        return f"{name} 0x{index:04X}" + (f":{sub}" if sub else "")

    def _sdo(self, index: int, sub: int, value: int | None = None) -> Any:
        """One SDO read (value None) or write, with errors that name the axis and object."""
        what = self._describe(index, sub) + ("" if value is None else f" = {value}")
        verb = "reading" if value is None else "writing"
        from canopen.sdo import SdoAbortedError, SdoCommunicationError
        try:
            var = self._sdo_var(index, sub)
            if value is None:
                return var.raw
            var.raw = value
            return None
        except KeyError as e:
            raise ObjectRefused(f"axis {self.name}: {what} is not in the EDS "
                                f"{self.eds_path.name}") from e
        except SdoAbortedError as e:
            raise ObjectRefused(f"axis {self.name}: drive node {self.node_id} refused "
                                f"{verb} {what}: {e}") from e
        except SdoCommunicationError as e:
            raise AxisError(f"axis {self.name}: no answer from drive node {self.node_id} on "
                            f"{self.interface}:{self.channel} {verb} {what}: {e}") from e

    def _read(self, index: int, sub: int = 0) -> Any:
        return self._sdo(index, sub)

    def _read_optional(self, index: int, sub: int = 0) -> Any:
        """None when the drive does not have the object (optional in CiA 301/402)."""
        try:
            return self._sdo(index, sub)
        except ObjectRefused:
            return None

    def _write(self, index: int, value: int, sub: int = 0) -> None:
        self._sdo(index, sub, int(value))
        self._journal("write", object=self._describe(index, sub), value=int(value))

    def _wait_real(self, done: Callable[[], bool], timeout_real_s: float, what: str,
                   check: bool = True, real_time: bool = False) -> None:
        """Wait for `done()` (TPDO readings, unless `real_time`: heartbeats). On a
        stepped clock a wait for readings is on stand time, its limit taken as clock s."""
        if stepped(self.clock) and not real_time:
            t_end = self.clock.now() + timeout_real_s
            real_end = time.monotonic() + timeout_real_s + REAL_MARGIN_S
            while True:
                if self._checked_done(done, check):
                    return
                if self.clock.now() > t_end or time.monotonic() > real_end:
                    raise AxisTimeout(f"axis {self.name}: timed out after {timeout_real_s:.2f} "
                                      f"s (stand time) waiting for {what}")
                before = self.clock.now()
                self.clock.sleep(max(self._tpdo_period_s, STEPPED_POLL_S))
                if self.clock.now() <= before:  # paused: nothing moves on stand time
                    with self._lock:
                        self._lock.wait(timeout=0.02)
        deadline = Deadline(timeout_real_s)
        while True:
            if check:
                self.check()
            with self._lock:
                if done():
                    return
                if deadline.expired():
                    raise AxisTimeout(f"axis {self.name}: timed out after {timeout_real_s:.2f} "
                                      f"s (real) waiting for {what}")
                self._lock.wait(timeout=0.02)

    def _checked_done(self, done: Callable[[], bool], check: bool) -> bool:
        """`done()` under the lock, once `check()` has raised any pending fault (if
        `check`): one look of a wait on stand time."""
        if check:
            self.check()
        with self._lock:
            return done()
