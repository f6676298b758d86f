"""The station's settings, parsed once by `bench serve` (serve.py), and the one test of
where a request comes from: read by the pages (app.py) and the signing (signing.py).

Each setting is declared once below, with its default, unit and meaning (a msgspec
Struct, as the stand's and the procedures' settings); `bench serve`'s options (serve.py)
set them.
"""

from __future__ import annotations

import ipaddress
from collections.abc import Iterable
from pathlib import Path
from typing import Annotated

from msgspec import Meta, Struct

#: the networks whose clients may enter a password over TLS unless the lab says otherwise
LOOPBACK_NETWORKS = ("127.0.0.0/8", "::1/128")
#: the Host names that are this machine itself (a browser on it)
LOOPBACK_NAMES = frozenset({"localhost", "127.0.0.1", "[::1]", "::1"})


def _d(description: str, unit: str | None = None) -> Meta:
    """A setting's meaning (and unit), declared where the setting is."""
    return Meta(description=description, extra={"unit": unit} if unit else None)


class StationSettings(Struct, frozen=True):
    """The station's settings: each declared once, with its default, unit and meaning
    (msgspec Meta, as the stand's and the procedures'); `bench serve`'s options set them."""

    runs: Annotated[Path, _d("the bench's runs folder the station serves")]
    token: Annotated[str, _d("the token for stop requests and remote viewers")]
    host: Annotated[str, _d("the address the station listens on")] = "127.0.0.1"
    port: Annotated[int, Meta(ge=0, le=65535, description="its TCP port")] = 8765
    records_url: Annotated[str, _d("the lab's records server")] | None = None
    register_url: Annotated[str, _d("the lab register (None: read-only, no "
                                    "login)")] | None = None
    lab_file: Annotated[str, _d("the lab file naming it, given to `bench "
                                "authorise`")] | None = None
    session_idle_s: Annotated[float, _d("a login ends after this long unused",
                                        "s")] = 15 * 60.0
    session_max_s: Annotated[float, _d("and this long after it began", "s")] = 8 * 3600.0
    trusted_proxy: Annotated[str, _d("the one proxy whose X-Forwarded-For names the client "
                                     "(None: the peer is the client)")] | None = None
    login_failures_per_client: Annotated[int, _d(
        "wrong logins from one client within login_window_s refuse its logins that "
        "long")] = 10
    login_window_s: Annotated[float, _d("the window of login_failures_per_client",
                                        "s")] = 15 * 60.0
    tls_cert: Annotated[Path, _d("the PEM certificate (with its chain) the station serves "
                                 "over TLS (None: plain HTTP)")] | None = None
    tls_key: Annotated[Path, _d("the PEM private key of that certificate (given with "
                                "tls_cert, never alone)")] | None = None
    password_networks: Annotated[tuple[str, ...], _d(
        "the networks whose clients may log in and sign over TLS (default: this machine "
        "only; `--passwords-from NET` adds the lab's); over plain HTTP a password is taken "
        "from this machine alone, whatever this says")] = LOOPBACK_NETWORKS
    server_names: Annotated[tuple[str, ...], _d(
        "names the station is reached by besides its address (the Host header is checked, "
        "and a browser on another machine names the server as its TLS certificate "
        "does)")] = ()
    other_runs: Annotated[tuple[Path, ...], _d(
        "other benches' runs folders this station can read (a share, a mount): their "
        "drafts' certificates are shown and signed here, as its own runs folder's "
        "are")] = ()

    @property
    def tls(self) -> bool:
        return self.tls_cert is not None

    @property
    def runs_folders(self) -> tuple[Path, ...]:
        """Every runs folder the station reads: its own first, then the other benches'."""
        return (self.runs, *self.other_runs)


def is_loopback(addr: str | None) -> bool:
    try:
        return ipaddress.ip_address((addr or "").split("%")[0]).is_loopback
    except ValueError:
        return False


def networks(texts: Iterable[str]) -> tuple[ipaddress.IPv4Network | ipaddress.IPv6Network, ...]:
    """The networks as written (`10.1.0.0/16`, `192.0.2.7`, `::1/128`); a malformed one is
    a ValueError naming it."""
    out = []
    for text in texts:
        try:
            out.append(ipaddress.ip_network(text.strip(), strict=False))
        except ValueError:
            raise ValueError(f"{text!r} is not a network or an address (e.g. 10.1.0.0/16, "
                             "192.0.2.7, ::1/128)") from None
    return tuple(out)


def in_networks(addr: str | None, nets: Iterable[str]) -> bool:
    try:
        ip = ipaddress.ip_address((addr or "").split("%")[0])
    except ValueError:
        return False
    return any(ip.version == n.version and ip in n for n in networks(nets))


def host_name(host_header: str) -> str:
    """The Host header without its port (`[::1]:8765` -> `[::1]`)."""
    if host_header.startswith("["):
        return host_header.split("]", 1)[0] + "]"
    return host_header.rsplit(":", 1)[0]


def is_loopback_host(host_header: str) -> bool:
    name = host_name(host_header).lower()
    return name in LOOPBACK_NAMES or is_loopback(name.strip("[]"))


def password_refusal(settings: StationSettings, *, tls: bool, client: str, peer: str,
                     host: str, forwarded: Iterable[str] = ()) -> str | None:
    """Why this request may not carry a password, in words; None when it may.

    Over TLS: its client (the peer, or behind the trusted proxy the address the proxy
    names) is in the lab's password networks. Over plain HTTP: from this machine alone,
    so a password never crosses a network in clear: the peer and the client loopback, the
    Host header this machine's own name, and no forwarding header naming another address
    (a proxy on this machine relaying plain HTTP from elsewhere)."""
    if tls:
        if in_networks(client, settings.password_networks):
            return None
        return (f"Passwords are accepted over TLS only from the lab's networks "
                f"({', '.join(settings.password_networks)}: the station's --passwords-from); "
                f"this request came from {client or 'an unknown address'}.")
    elsewhere = [a for a in forwarded if a and not is_loopback(a)]
    if is_loopback(peer) and is_loopback(client) and is_loopback_host(host) and not elsewhere:
        return None
    why = (f"the Host header names {host_name(host)}" if not is_loopback_host(host) else
           f"it was forwarded for {elsewhere[0]}" if elsewhere else
           f"it came from {client or peer or 'an unknown address'}")
    return ("Passwords are not accepted over plain HTTP from another machine (" + why +
            "): a password would cross the network in clear. Log in at the bench itself "
            "(http://127.0.0.1), or open the station over HTTPS (bench serve --tls-cert FILE "
            "--tls-key FILE, docs/station.md).")
