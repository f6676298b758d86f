"""Node ids on the stand's CAN buses: the controller id each axis's drive watches.

Truth: hand-assigned ids (CiA 301: one producer per heartbeat COB-ID), and a drive twin
pair on one real python-can virtual bus, where a controller that dies must have its own
axis stopped however long the other axis's controller keeps running.
"""

from __future__ import annotations

import time
import uuid

import msgspec
import pytest

from bench.core.canbus import AxisBus
from bench.core.canbus import bus_problems as _bus_problems
from bench.core.canbus import controller_node_ids as _controller_node_ids
from drivers.axis import Axis
from drivers.cia402 import State
from sims.clock import VirtualClock
from sims.stand import AxisTruth, SimulatedStand, StandTruth
from tests.conftest import Twins, drive_settings


def bus_problems(axes: dict[str, dict]) -> list[tuple[tuple[str, ...], str]]:
    return _bus_problems(msgspec.convert(axes, dict[str, AxisBus]))


def controller_node_ids(axes: dict[str, dict]) -> dict[str, int]:
    return _controller_node_ids(msgspec.convert(axes, dict[str, AxisBus]))


def _axes(*drives: dict) -> dict[str, dict]:
    return {f"a{i}": {"drive": {"interface": "socketcan", "channel": "can0", **d}}
            for i, d in enumerate(drives)}


def test_axes_on_one_bus_get_their_own_controller_ids() -> None:
    assert controller_node_ids(_axes({"node_id": 2}, {"node_id": 3})) == {"a0": 127, "a1": 126}
    # a drive at 127 pushes the controllers down; an explicit id is kept and skipped
    assert controller_node_ids(_axes({"node_id": 127}, {"node_id": 3})) == {"a0": 126,
                                                                           "a1": 125}
    assert controller_node_ids(_axes({"node_id": 2}, {"node_id": 3, "controller_node_id": 127})
                               ) == {"a0": 126, "a1": 127}
    # separate buses do not share ids
    two = _axes({"node_id": 2}, {"node_id": 2})
    two["a1"]["drive"]["channel"] = "can1"
    assert controller_node_ids(two) == {"a0": 127, "a1": 127}
    assert bus_problems(two) == []


def test_an_id_used_twice_on_a_bus_is_named_at_its_key() -> None:
    problems = bus_problems(_axes({"node_id": 2}, {"node_id": 2},
                                  {"node_id": 4, "controller_node_id": 4}))
    assert [p for p, _ in problems] == [("a1", "drive", "node_id"),
                                        ("a2", "drive", "controller_node_id")]
    assert "node id 2 on CAN bus socketcan:can0 is already axis 'a0''s drive" in problems[0][1]
    assert "already axis 'a2''s drive" in problems[1][1]


@pytest.mark.timeout(30)
def test_one_dead_controller_stops_its_own_axis_on_a_shared_bus(twins: Twins) -> None:
    clock = VirtualClock(50.0)
    stand = SimulatedStand(StandTruth(seed=3, axes={"outer": AxisTruth(), "inner": AxisTruth()}),
                           {"outer": 200.0, "inner": 200.0}, clock)
    channel = f"test-bus-{uuid.uuid4().hex[:10]}"
    axes = {"outer": {"drive": {"interface": "virtual", "channel": channel, "node_id": 2}},
            "inner": {"drive": {"interface": "virtual", "channel": channel, "node_id": 3}}}
    ids = controller_node_ids(axes)
    assert ids == {"outer": 127, "inner": 126}
    drives = {a: twins.drive(stand, a, channel=channel, node_id=axes[a]["drive"]["node_id"])
              for a in axes}
    drivers = {a: Axis(a, drive_settings(channel, axes[a]["drive"]["node_id"],
                                         controller_node_id=ids[a], max_rate_dps=100.0,
                                         max_accel_dps2=500.0, heartbeat_ms=50,
                                         watchdog_ms=200),
                       clock=clock, feedback_journal_s=0.0)
               for a in axes}
    try:
        for ax in drivers.values():
            ax.open()
            ax.set_rate(30.0)
        for ax in drivers.values():
            ax.wait_settled(0.02, 0.5, 30.0)
        network = drivers["outer"].network
        assert network is not None
        network.disconnect()                 # the outer axis's controller dies
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline and not drives["outer"].watchdog_trips:
            time.sleep(0.01)
        assert drives["outer"].watchdog_trips, "the outer drive's watchdog is fed by another node"
        trip = drives["outer"].watchdog_trips[0]
        assert 0.2 <= trip.silence_s <= 0.3          # its own 200 ms, not fed by the other
        time.sleep(0.5)                              # the other axis runs on, untouched
        assert drives["inner"].watchdog_trips == []
        assert drives["inner"].state is State.OPERATION_ENABLED
        assert abs(drivers["inner"].rate_dps - 30.0) < 0.02
    finally:
        drivers["inner"].close()
