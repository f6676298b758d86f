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

from bench.core.yamlfile import KeyPath
from drivers.cia402 import CONTROLLER_NODE_ID  # further axes on a bus take 0x7E, 0x7D, ...
from drivers.drive_settings import bus_name as bus_name  # a bus's identity, the drive's


def _node_id(drive: Mapping[str, object], key: str) -> int:
    """A validated node id (the schema says an integer)."""
    v = drive[key]
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise ValueError(f"drive.{key} is {v!r}, not a node id")
    return int(v)


def controller_node_ids(axes: Mapping[str, Mapping[str, Mapping[str, object]]]
                        ) -> dict[str, int]:
    """Per axis: its drive's `controller_node_id` if the stand gives one, or else the
    highest node id still free on its bus (0x7F, 0x7E, ... in the stand file's order)."""
    used: dict[str, set[int]] = {}
    for ax in axes.values():
        d = ax["drive"]
        used.setdefault(bus_name(d), set()).update(
            {_node_id(d, "node_id")} | ({_node_id(d, "controller_node_id")}
                                        if "controller_node_id" in d else set()))
    out = {}
    for name, ax in axes.items():
        d = ax["drive"]
        if "controller_node_id" in d:
            out[name] = _node_id(d, "controller_node_id")
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


def bus_problems(axes: Mapping[str, object]) -> list[tuple[KeyPath, str]]:
    """Node ids used twice on one bus, each named at the key that repeats it; a bus
    behind a server (socketcand) without the server's address."""
    out: list[tuple[KeyPath, str]] = []
    for name, ax in axes.items():
        d = ax.get("drive") if isinstance(ax, Mapping) else None
        if not isinstance(d, Mapping):
            continue
        for key in SERVER_KEYS.get(str(d.get("interface")), ()):
            if key not in d:
                out.append(((name, "drive", "interface"),
                            f"interface {d.get('interface')} needs drive.{key} (the server's "
                            f"{'address, e.g. 127.0.0.1' if key == 'host' else 'TCP port'})"))
    seen: dict[tuple[str, int], str] = {}      # (bus, node id) -> what holds it
    keys = [("node_id", "drive"), ("controller_node_id", "controller")]
    for key, role in keys:
        for name, ax in axes.items():
            d = ax.get("drive") if isinstance(ax, Mapping) else None
            if not isinstance(d, Mapping) or key not in d:
                continue
            where = (bus_name(d), int(d[key]))
            if where in seen:
                out.append(((name, "drive", key),
                            f"node id {where[1]} on CAN bus {where[0]} is already axis "
                            f"{seen[where]}; every node on a bus needs its own id"))
            else:
                seen[where] = f"{name!r}'s {role}"
    return out
