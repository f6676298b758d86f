"""The station's settings, parsed once by `bench serve` (serve.py), and the one test of
where a request comes from: read by the pages (app.py) and the signing (signing.py)."""

from __future__ import annotations

import ipaddress
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class StationSettings:
    runs: Path
    token: str
    host: str = "127.0.0.1"
    port: int = 8765
    records_url: str | None = None
    register_url: str | None = None     # the lab register (None: read-only, no login)
    lab_file: str | None = None         # the lab file naming it, given to `bench authorise`
    session_idle_s: float = 15 * 60.0   # a login ends after this long unused
    session_max_s: float = 8 * 3600.0   # and this long after it began
    #: the one proxy whose X-Forwarded-For names the client (None: the peer is the client)
    trusted_proxy: str | None = None
    login_failures_per_client: int = 10     # wrong logins from one client within ...
    login_window_s: float = 15 * 60.0       # ... this long refuse its logins that long


def is_loopback(addr: str | None) -> bool:
    try:
        return ipaddress.ip_address((addr or "").split("%")[0]).is_loopback
    except ValueError:
        return False
