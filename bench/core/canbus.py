"""The stand's CAN buses: which axes share one, and the node ids each bus carries.

Each axis's drive driver is a controller node of its own on its bus (its own canopen
Network, heartbeat producer and SDO client), and that axis's drive watches exactly that
node's heartbeat (0x1016:1). So axes on one bus (same interface and channel) need
distinct drive node ids and distinct controller node ids: with one controller id for
two axes, either axis's heartbeat would keep the other drive's watchdog fed, and two
producers of one heartbeat COB-ID on a bus break CiA 301.
"""

from __future__ import annotations

from collections.abc import Mapping

from msgspec import Struct

from bench.core.yamlfile import KeyPath
from drivers.cia402 import CONTROLLER_NODE_ID  # further axes on a bus take 0x7E, 0x7D, ...
from drivers.drive_settings import NodeId
from drivers.drive_settings import bus_name as bus_name  # a bus's identity, the drive's


class BusNode(Struct, frozen=True, kw_only=True):
    """A drive block's place on its bus, read before the block is built (its controller
    id is given from the others'); its other keys are the drive's (DriveSettings)."""

    interface: str
    channel: str
    host: str | None = None
    port: int | None = None
    node_id: NodeId
    controller_node_id: NodeId | None = None


class AxisBus(Struct, frozen=True, kw_only=True):
    """An axis of the stand file as the bus check reads it: its drive's bus and ids."""

    drive: BusNode


def controller_node_ids(axes: Mapping[str, AxisBus]) -> dict[str, int]:
    """Per axis: its drive's `controller_node_id` if the stand gives one, or else the
    highest node id still free on its bus (0x7F, 0x7E, ... in the stand file's order)."""
    used: dict[str, set[int]] = {}
    for ax in axes.values():
        d = ax.drive
        used.setdefault(bus_name(d), set()).update(
            {d.node_id} | ({d.controller_node_id} if d.controller_node_id is not None
                           else set()))
    out = {}
    for name, ax in axes.items():
        d = ax.drive
        if d.controller_node_id is not None:
            out[name] = d.controller_node_id
            continue
        taken = used[bus_name(d)]
        node = CONTROLLER_NODE_ID
        while node in taken:
            node -= 1
        taken.add(node)
        out[name] = node
    return out


#: interfaces whose bus sits behind a server the stand must name (python-can's arguments)
SERVER_KEYS = {"socketcand": ("host", "port")}


def bus_problems(axes: Mapping[str, AxisBus]) -> list[tuple[KeyPath, str]]:
    """Node ids used twice on one bus, each named at the key that repeats it; a bus
    behind a server (socketcand) without the server's address."""
    out: list[tuple[KeyPath, str]] = []
    for name, ax in axes.items():
        d = ax.drive
        for key in SERVER_KEYS.get(d.interface, ()):
            if getattr(d, key) is None:
                out.append(((name, "drive", "interface"),
                            f"interface {d.interface} needs drive.{key} (the server's "
                            f"{'address, e.g. 127.0.0.1' if key == 'host' else 'TCP port'})"))
    seen: dict[tuple[str, int], str] = {}      # (bus, node id) -> what holds it
    keys = [("node_id", "drive"), ("controller_node_id", "controller")]
    for key, role in keys:
        for name, ax in axes.items():
            node: int | None = getattr(ax.drive, key)
            if node is None:
                continue
            where = (bus_name(ax.drive), node)
            if where in seen:
                out.append(((name, "drive", key),
                            f"node id {where[1]} on CAN bus {where[0]} is already axis "
                            f"{seen[where]}; every node on a bus needs its own id"))
            else:
                seen[where] = f"{name!r}'s {role}"
    return out
