"""The network guard's check, shared by the pytest plugin (tests/netguard.py) and the
sitecustomize next to this file, so the test process and every Python subprocess a test
starts refuse the same addresses the same way.

The test suite must never reach past the machine: a twin, a driver or a library that
quietly talks to a lab address, a DNS name or a multicast group would make the tests
depend on the network they run on, and on a lab network could reach a real instrument.
The guard patches the methods of `socket.socket` (a Python class over the C socket), so
it sees every connect and send made through Python's socket API, asyncio's and ssl's
included, before the system call: a refused address is never contacted. A host name other
than localhost is refused unresolved, in connect and in socket.getaddrinfo (which
create_connection, http.client and asyncio call first), since the lookup is itself a
query to a name server. Each refusal is
recorded before the PermissionError is raised, since a library that retries or catches
OSError would otherwise hide the attempt. This module needs nothing but the standard
library: a subprocess imports it at start-up, before any of the project is importable.
"""

from __future__ import annotations

import ipaddress
import json
import os
import socket
import sys
import threading
import traceback
from collections.abc import Callable
from typing import Any, TypedDict

#: the file a process appends its refused attempts to, one JSON object a line
ENV_LOG = "RATEBENCH_NETGUARD_LOG"

_LINUX = sys.platform.startswith("linux")
#: multicast joins (setsockopt level -> option numbers); the MCAST_* and source-specific
#: options are not named by Python's socket module, so their Linux numbers are used
_JOINS: dict[int, frozenset[int]] = {
    socket.IPPROTO_IP: frozenset(
        {socket.IP_ADD_MEMBERSHIP}
        | ({39, 42, 46} if _LINUX else set())),   # IP_ADD_SOURCE_MEMBERSHIP, MCAST_JOIN_*
    socket.IPPROTO_IPV6: frozenset(
        {socket.IPV6_JOIN_GROUP}                   # = IPV6_ADD_MEMBERSHIP
        | ({42, 46} if _LINUX else set())),        # MCAST_JOIN_GROUP, MCAST_JOIN_SOURCE_GROUP
}
_INET = (socket.AF_INET, socket.AF_INET6)
_STACK_FRAMES = 8
_HERE = os.path.abspath(__file__)


class Attempt(TypedDict):
    """One refused attempt, as recorded (and as one line of a log file)."""

    call: str        # connect, connect_ex, sendto, sendmsg, setsockopt, getaddrinfo
    address: str     # host:port, [v6]:port, or "multicast group G"
    pid: int
    argv: str        # the process, to tell a subprocess's attempt from the test's own
    stack: list[str]  # where it came from, innermost last


_lock = threading.Lock()
_records: list[Attempt] = []
_state: dict[str, bool] = {"installed": False, "to_file": False}
_originals: dict[str, Callable[..., Any]] = {}


def is_local_host(host: str) -> bool:
    """127.0.0.0/8, ::1, ::ffff:127.x and the name "localhost"; every other name is
    refused without resolving it (the lookup would itself be a query to the network)."""
    name = host.strip().lower()
    if name in ("localhost", "localhost."):
        return True
    try:
        ip = ipaddress.ip_address(name)
    except ValueError:
        return False
    if ip.is_loopback:
        return True
    return (isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None
            and ip.ipv4_mapped.is_loopback)


def refused_address(family: int, address: object) -> str | None:
    """The address as printed if a connect or send to it must be refused, else None.
    Families other than IPv4/IPv6 (AF_UNIX, AF_CAN, netlink) stay on the machine; an
    address of the wrong shape is left for the socket itself to reject."""
    if family not in _INET or not isinstance(address, tuple) or len(address) < 2:
        return None
    host, port = address[0], address[1]
    if isinstance(host, bytes | bytearray):
        host = bytes(host).decode("ascii", "replace")
    if not isinstance(host, str):
        return None
    if is_local_host(host):
        return None
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def refused_lookup(host: object, port: object) -> str | None:
    """The name as printed if resolving it must be refused (a DNS query leaves the
    machine): any name but localhost; numeric addresses resolve locally and are left to
    the connect or send that follows."""
    if isinstance(host, bytes | bytearray):
        host = bytes(host).decode("ascii", "replace")
    if not isinstance(host, str) or not host or is_local_host(host):
        return None
    try:
        ipaddress.ip_address(host)
    except ValueError:
        return f"{host}:{port}"
    return None


def multicast_group(level: int, option: int, value: object) -> str | None:
    """The group a setsockopt would join, as printed, or None if it joins none."""
    if option not in _JOINS.get(level, frozenset()):
        return None
    group = "?"
    if isinstance(value, bytes | bytearray):
        raw = bytes(value)
        try:
            if option in (42, 46) and _LINUX and len(raw) >= 16:    # struct group_req
                fam = int.from_bytes(raw[8:10], sys.byteorder)
                if fam == socket.AF_INET:
                    group = socket.inet_ntop(socket.AF_INET, raw[12:16])
                elif fam == socket.AF_INET6 and len(raw) >= 32:
                    group = socket.inet_ntop(socket.AF_INET6, raw[16:32])
            elif level == socket.IPPROTO_IPV6 and len(raw) >= 16:   # struct ipv6_mreq
                group = socket.inet_ntop(socket.AF_INET6, raw[:16])
            elif len(raw) >= 4:                                     # struct ip_mreq(n)
                group = socket.inet_ntop(socket.AF_INET, raw[:4])
        except (OSError, ValueError):
            pass
    return f"multicast group {group}"


def _stack() -> list[str]:
    frames = [f for f in traceback.extract_stack() if os.path.abspath(f.filename) != _HERE]
    return [f"{f.filename}:{f.lineno} in {f.name}" for f in frames[-_STACK_FRAMES:]]


def append_log(path: str, attempts: list[Attempt]) -> None:
    """Append attempts to a log file, each line in one write (O_APPEND), so processes
    sharing the file do not interleave within a line."""
    if not attempts:
        return
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        for a in attempts:
            os.write(fd, (json.dumps(a) + "\n").encode())
    finally:
        os.close(fd)


def read_log(path: str) -> list[Attempt]:
    """A log file's attempts (none if it does not exist; a torn line is kept as text)."""
    try:
        with open(path, encoding="utf-8") as f:
            lines = [ln for ln in f.read().splitlines() if ln.strip()]
    except FileNotFoundError:
        return []
    out: list[Attempt] = []
    for ln in lines:
        try:
            out.append(json.loads(ln))
        except ValueError:
            out.append(Attempt(call="?", address=ln[:200], pid=0, argv="", stack=[]))
    return out


def _refuse(call: str, address: str) -> PermissionError:
    attempt = Attempt(call=call, address=address, pid=os.getpid(),
                      argv=" ".join(sys.argv)[:200], stack=_stack())
    log = os.environ.get(ENV_LOG)
    with _lock:
        if _state["to_file"] and log:
            try:
                append_log(log, [attempt])
            except OSError:
                _records.append(attempt)
        else:
            _records.append(attempt)
    return PermissionError(13, f"network guard: {call} to {address} refused (tests may "
                               "reach only 127.0.0.0/8, ::1 and localhost)")


def drain() -> list[Attempt]:
    """The attempts recorded in this process since the last drain."""
    with _lock:
        out = list(_records)
        _records.clear()
    return out


def log_to_file(on: bool) -> None:
    """Refused attempts go to the file $RATEBENCH_NETGUARD_LOG names (a subprocess, read
    after it may have exited) or are kept in memory for `drain` (the pytest process)."""
    _state["to_file"] = on


def _after_fork() -> None:
    # a forked child (multiprocessing) is another process: its attempts go to the log
    # file, which the parent reads, not to a copy of the parent's memory
    global _lock
    _lock = threading.Lock()
    _records.clear()
    _state["to_file"] = True


def install() -> None:
    """Patch socket.socket and socket.getaddrinfo (once per process)."""
    if _state["installed"]:
        return
    cls = socket.socket
    for name in ("connect", "connect_ex", "sendto", "sendmsg", "setsockopt"):
        _originals[name] = getattr(cls, name)
    connect, connect_ex = _originals["connect"], _originals["connect_ex"]
    sendto, sendmsg, setsockopt = (_originals["sendto"], _originals["sendmsg"],
                                   _originals["setsockopt"])

    def guarded_connect(self: socket.socket, address: Any) -> None:
        bad = refused_address(self.family, address)
        if bad is not None:
            raise _refuse("connect", bad)
        connect(self, address)

    def guarded_connect_ex(self: socket.socket, address: Any) -> int:
        bad = refused_address(self.family, address)
        if bad is not None:
            raise _refuse("connect_ex", bad)
        return int(connect_ex(self, address))

    def guarded_sendto(self: socket.socket, data: Any, *args: Any) -> int:
        if args:    # sendto(data, address) or sendto(data, flags, address)
            bad = refused_address(self.family, args[-1])
            if bad is not None:
                raise _refuse("sendto", bad)
        return int(sendto(self, data, *args))

    def guarded_sendmsg(self: socket.socket, *args: Any) -> int:
        if len(args) >= 4 and args[3] is not None:   # buffers, ancdata, flags, address
            bad = refused_address(self.family, args[3])
            if bad is not None:
                raise _refuse("sendmsg", bad)
        return int(sendmsg(self, *args))

    def guarded_setsockopt(self: socket.socket, level: int, option: int, *args: Any) -> None:
        group = multicast_group(level, option, args[0] if args else None)
        if group is not None:
            raise _refuse("setsockopt", group)
        setsockopt(self, level, option, *args)

    getaddrinfo = socket.getaddrinfo
    _originals["getaddrinfo"] = getaddrinfo

    def guarded_getaddrinfo(host: Any, port: Any, *args: Any, **kwargs: Any) -> Any:
        bad = refused_lookup(host, port)
        if bad is not None:
            raise _refuse("getaddrinfo", bad)
        return getaddrinfo(host, port, *args, **kwargs)

    socket.getaddrinfo = guarded_getaddrinfo
    for name, fn in (("connect", guarded_connect), ("connect_ex", guarded_connect_ex),
                     ("sendto", guarded_sendto), ("sendmsg", guarded_sendmsg),
                     ("setsockopt", guarded_setsockopt)):
        fn.__name__ = fn.__qualname__ = name
        setattr(cls, name, fn)
    os.register_at_fork(after_in_child=_after_fork)
    _state["installed"] = True
