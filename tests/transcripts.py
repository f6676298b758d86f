"""Manual transcripts: literal exchanges written from the instruments' manuals.

Each transcript is a list of (sent, reply) pairs (drivers/transport.py). A driver test
runs the driver against one with no server (`expected_protocol`); `replay_on_twin` sends
the same lines to the twin over its real TCP channel and checks the twin's replies: a
literal reply must come back as written, a `Like` reply must match its pattern (the
twin's numbers come from the stand's truth, so only their form is fixed).
"""

from __future__ import annotations

import socket

from drivers.transport import Exchange, Like

NO_ERROR_KEYSIGHT = '+0,"No error"'   # 53220A/53230A Programmer's Reference, SYSTem:ERRor?
NO_ERROR_PENDULUM = '0,"No error"'    # CNT-90 series Programmer's Handbook, :SYSTem:ERRor?

#: one NR3 number as the 53230A prints it: `+1.29383828200000E-006` (p. 377)
NR3_KEYSIGHT = r"[+-]\d\.\d+E[+-]\d{3}"


def checked(command: str, no_error: str = NO_ERROR_KEYSIGHT) -> list[Exchange]:
    """A setting, then SYST:ERR? (the driver checks the error queue after each write)."""
    return [(command, None), ("SYST:ERR?", no_error)]


def replay_on_twin(resource: str, exchanges: list[Exchange], timeout_s: float = 10.0
                   ) -> list[str]:
    """Send every line to the twin; raise AssertionError at the first wrong reply."""
    host, port = resource.split("::")[1], int(resource.split("::")[2])
    got: list[str] = []
    with socket.create_connection((host, port), timeout=timeout_s) as sock:
        f = sock.makefile("rwb")
        for i, (sent, reply) in enumerate(exchanges):
            f.write((sent + "\n").encode("ascii"))
            f.flush()
            if reply is None:
                continue
            line = f.readline().decode("ascii").rstrip("\r\n")
            got.append(line)
            ok = reply.matches(line) if isinstance(reply, Like) else line == reply
            if not ok:
                want = reply.pattern if isinstance(reply, Like) else reply
                raise AssertionError(f"exchange {i + 1} ({sent!r}): the twin replied "
                                     f"{line[:120]!r}, the manual's transcript has {want!r}")
    return got
