"""The controller's heartbeat stops when the controller stops, so the drive stops the table.

The suspended-controller test runs the controller in a second process and the drive twin
here, on the twin's virtual bus served by a socketcand server on 127.0.0.1 (a real
channel between processes: the virtual bus is per process; sims/socketcand_server.py). SocketCAN, where the bus's own periodic task would be a kernel task
that outlives a suspended process, is out of a twin's reach (it needs the vcan module and
root), so one test stands in for it by taking `send_periodic` away from the bus.
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import threading
import time

import can
import pytest

from drivers.axis import Axis
from drivers.cia402 import State
from drivers.heartbeat import HeartbeatProducer
from sims.clock import VirtualClock
from sims.drive_twin import DriveTwin
from sims.socketcand_server import SocketcandServer
from sims.stand import AxisTruth, SimulatedStand, StandTruth
from tests.conftest import ROOT, Twins, drive_settings, one_axis_stand

CONTROLLER = """
import sys, time
from drivers.clock import MonotonicClock
from drivers.axis import Axis
from drivers.drive_settings import DriveSettings
ax = Axis("outer", DriveSettings(interface="socketcand", channel="bench", host="127.0.0.1",
                                 port=int(sys.argv[1]), node_id=2, max_rate_dps=100.0,
                                 max_accel_dps2=500.0, heartbeat_ms=50, watchdog_ms=300),
          clock=MonotonicClock())
ax.open()
ax.set_rate(20.0)
print("running", flush=True)
time.sleep(120)
"""


class Recorder:
    """A sink for frames: when each was sent."""

    def __init__(self, stall_at: int | None = None, stall_s: float = 0.0) -> None:
        self.times: list[float] = []
        self.stall_at, self.stall_s = stall_at, stall_s

    def send_message(self, can_id: int, data: bytes, remote: bool = False) -> None:
        self.times.append(time.monotonic())
        if len(self.times) == self.stall_at:
            time.sleep(self.stall_s)


def test_period_is_kept_and_a_stall_is_not_made_up_by_a_burst() -> None:
    rec = Recorder(stall_at=5, stall_s=0.25)
    hb = HeartbeatProducer(rec, 0x77F, b"\x05", 0.02).start()
    time.sleep(0.6)
    hb.stop()
    gaps = [b - a for a, b in zip(rec.times, rec.times[1:], strict=False)]
    assert gaps[4] >= 0.24                              # the stall shows on the bus
    # no catch-up burst after it: the 12 missed periods would all go out at once
    resumed = rec.times[5]
    assert sum(resumed <= t <= resumed + 0.1 for t in rec.times) <= 0.1 / 0.02 + 2
    assert 0.015 <= sorted(gaps)[len(gaps) // 2] <= 0.04
    n = hb.sent
    time.sleep(0.1)
    assert hb.sent == n                                 # stopped means stopped


@pytest.mark.timeout(20)
def test_heartbeat_does_not_use_the_bus_periodic_task(monkeypatch: pytest.MonkeyPatch,
                                                      twins: Twins) -> None:
    """Stand-in for SocketCAN's kernel task (see the module docstring): with the bus's
    `send_periodic` taken away, the axis still heartbeats and its drive hears it."""
    real = can.BusABC.send_periodic

    def refuse_ours(bus: can.BusABC, msgs: can.Message, *args: object, **kw: object) -> object:
        if isinstance(msgs, can.Message) and msgs.arbitration_id == 0x77F:
            raise AssertionError("the controller's heartbeat must not be a bus periodic task")
        return real(bus, msgs, *args, **kw)       # the drive twin's own heartbeat (0x702)

    clock = VirtualClock(20.0)
    twin = twins.drive(one_axis_stand(clock, seed=2, max_rate_dps=100.0), node_id=2)
    monkeypatch.setattr(can.BusABC, "send_periodic", refuse_ours)
    with Axis("outer", drive_settings(twin.channel, max_rate_dps=100.0, max_accel_dps2=500.0,
                                      heartbeat_ms=50, watchdog_ms=200), clock=clock) as ax:
        ax.set_rate(10.0)
        time.sleep(0.6)                              # three watchdog times
        assert twin.watchdog_trips == [] and twin.state is State.OPERATION_ENABLED


@pytest.mark.timeout(60)
def test_a_suspended_controller_has_its_table_stopped() -> None:
    """Ctrl-Z (SIGSTOP here) on the controller: the drive's watchdog trips after its time."""
    clock = VirtualClock(1.0)
    stand = SimulatedStand(StandTruth(seed=4, axes={"outer": AxisTruth()}), {"outer": 100.0},
                           clock)
    channel = f"hb-{random.getrandbits(40):010x}"
    twin = DriveTwin(stand, "outer", drive_settings(channel))
    twin.start()
    server = SocketcandServer({"bench": channel})
    port = server.start()
    proc = subprocess.Popen([sys.executable, "-c", CONTROLLER, str(port)], cwd=ROOT, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        line: list[str] = []
        reader = threading.Thread(target=lambda: line.append(proc.stdout.readline()))
        reader.start()
        reader.join(30)
        assert line and line[0].strip() == "running", proc.stderr.read() if proc.poll() else ""
        time.sleep(0.5)                                  # heartbeats flow, no trip
        assert twin.watchdog_trips == [] and twin.state is State.OPERATION_ENABLED
        assert stand.axes["outer"].commanded_rate_at(clock.now()) == pytest.approx(20.0, abs=1e-6)
        os.kill(proc.pid, signal.SIGSTOP)
        deadline = time.monotonic() + 5.0
        while not twin.watchdog_trips and time.monotonic() < deadline:
            time.sleep(0.01)
        assert twin.watchdog_trips, "the drive still hears a suspended controller"
        assert 0.3 <= twin.watchdog_trips[0].silence_s <= 0.6   # its own 300 ms
        deadline = time.monotonic() + 2.0                # quick stop, then FAULT
        while twin.state is not State.FAULT and time.monotonic() < deadline:
            time.sleep(0.01)
        assert twin.state is State.FAULT
        assert stand.axes["outer"].commanded_rate_at(clock.now() + 1.0) == 0.0   # stopping
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        os.kill(proc.pid, signal.SIGCONT)
        proc.wait(10)
        server.stop()
        twin.stop()


@pytest.mark.timeout(60)
def test_a_twin_held_up_inside_its_own_process_does_not_take_that_for_silence(
        twins: Twins) -> None:
    """The stand's lock held for 1.2 s (another twin generating samples on a loaded host)
    holds the drive twin's tick, while the controller's heartbeats flow on the bus. A real
    drive receives on a CAN controller of its own, so it must not trip; the twin did (CI
    beside two busy processes: "no heartbeat from node 126 for 7.563 s" in a run whose
    controller was sending). The same twin still trips on a real silence, in its time."""
    clock = VirtualClock(50.0)
    stand = SimulatedStand(StandTruth(seed=5, axes={"outer": AxisTruth()}), {"outer": 200.0},
                           clock)
    twin = twins.drive(stand)
    ax = Axis("outer", drive_settings(twin.channel, max_rate_dps=100.0, max_accel_dps2=500.0,
                                      heartbeat_ms=50, watchdog_ms=200),
              clock=clock, feedback_journal_s=0.0)
    silent = False
    try:
        ax.open()
        ax.set_rate(30.0)
        ax.wait_settled(0.02, 0.5, 30.0)
        with stand.axes["outer"].lock:       # six watchdog times
            time.sleep(1.2)
        time.sleep(0.3)
        assert twin.watchdog_trips == [], "the twin's own hold taken for the controller's"
        assert twin.state is State.OPERATION_ENABLED
        assert ax.network is not None
        silent = True
        ax.network.disconnect()              # the controller goes silent
        deadline = time.monotonic() + 3.0
        while not twin.watchdog_trips and time.monotonic() < deadline:
            time.sleep(0.01)
        assert twin.watchdog_trips, "a silent controller not noticed"
        assert 0.2 <= twin.watchdog_trips[0].silence_s <= 0.4   # its own 200 ms
    finally:
        if not silent:  # a disconnected controller has nothing left to stop with
            ax.close()
