"""The controller's CANopen heartbeat (CiA 301), sent from a thread of this process.

The drive's heartbeat consumer (0x1016) is the table's last line of defence: when our
heartbeat stops, the drive stops the axis. So the heartbeat must stop whenever the
controller stops. python-can's `send_periodic` does not promise that: on SocketCAN it is
a kernel broadcast-manager task that goes on sending while this process is suspended
(Ctrl-Z, SIGSTOP, a debugger, a laptop lid) and keeps a spinning table's watchdog fed.
A thread of ours is suspended with the process and ends with it.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Protocol

log = logging.getLogger(__name__)


class Sender(Protocol):
    def send_message(self, can_id: int, data: bytes, remote: bool = False) -> None: ...


class HeartbeatProducer:
    """Sends `data` on `cob_id` every `period_s` until `stop()`; never raises from its thread."""

    def __init__(self, sender: Sender, cob_id: int, data: bytes, period_s: float,
                 name: str = "heartbeat") -> None:
        if not period_s > 0:
            raise ValueError(f"heartbeat period must be > 0 s, got {period_s}")
        self.sender, self.cob_id, self.data, self.period_s = sender, cob_id, bytes(data), period_s
        self.sent = 0
        #: when this thread last woke more than a period late (time.monotonic()): the host
        #: starved the process, so whatever the drive sent meanwhile may not have been read
        self.host_stall_end = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> HeartbeatProducer:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout=2 * self.period_s + 1.0)

    def _run(self) -> None:
        next_t = time.monotonic()
        failing = False
        while True:
            now = time.monotonic()
            if now - next_t > self.period_s:
                self.host_stall_end = now
            try:
                self.sender.send_message(self.cob_id, self.data)
                self.sent += 1
                if failing:
                    log.warning("heartbeat 0x%03X: sending again", self.cob_id)
                failing = False
            except Exception as e:  # noqa: BLE001 - the drive's watchdog covers a silent bus
                if not failing:
                    log.error("heartbeat 0x%03X: cannot send: %s", self.cob_id, e)
                failing = True
            # a fixed grid, but never a burst to catch up after a stall (a stall is what
            # the drive must see)
            next_t = max(next_t + self.period_s, time.monotonic())
            if self._stop.wait(max(0.0, next_t - time.monotonic())):
                return
