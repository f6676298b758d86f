"""`bench serve`: the station view on a local port (waitress, a production WSGI server), or
over TLS (`--tls-cert`/`--tls-key`: cheroot, a production WSGI server with TLS through
Python's own ssl module; issue 59)."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import ssl

    from cheroot import wsgi
    from flask import Flask

    # every `bench` command builds serve's parser; the settings (ipaddress, dataclasses)
    # and `secrets` load only when `bench serve` runs (bench validate's start-up budget)
    from bench.app.station.settings import StationSettings

TOKEN_ENV = "BENCH_STATION_TOKEN"
LAB_ENV = "BENCH_LAB_SETTINGS"      # the lab file, as bench authorise and the DCC read it
THREADS = 16        # each open live page holds one thread for its event stream


def add_serve_arguments(srv: argparse.ArgumentParser) -> None:
    """`bench serve`'s options (bench/app/cli.py calls this for its subparser)."""
    srv.add_argument("--runs", default="runs", help="the runs folder to show (runs/)")
    srv.add_argument("--records", metavar="URL", help="records database URL")
    srv.add_argument("--port", type=int, default=8765, help="TCP port (8765; 0 picks one)")
    srv.add_argument("--host", default="127.0.0.1",
                     help="address to bind (127.0.0.1); another one needs --token")
    srv.add_argument("--token", help="token for stop requests and remote viewers "
                                     "(default: $BENCH_STATION_TOKEN, else one is made up)")
    srv.add_argument("--register", metavar="URL",
                     help="the lab register whose accounts log in and sign (default: the "
                          "lab file's register:); without one the station is read-only")
    srv.add_argument("--trusted-proxy", metavar="ADDR",
                     help="the reverse proxy in front of the station: only its "
                          "X-Forwarded-For names the client (login limits per client)")
    srv.add_argument("--lab", metavar="FILE",
                     help=f"the lab file naming the register, given to bench authorise "
                          f"when a draft is signed (default: ${LAB_ENV})")
    srv.add_argument("--other-runs", metavar="DIR", action="append", default=[],
                     help="another bench's runs folder this station reads (a share): its "
                          "drafts' certificates are shown and signed here (repeatable)")
    srv.add_argument("--tls-cert", metavar="FILE",
                     help="serve over TLS (HTTPS) with this PEM certificate (its chain "
                          "after it); with --tls-key")
    srv.add_argument("--tls-key", metavar="FILE", help="the PEM private key of --tls-cert")
    srv.add_argument("--passwords-from", metavar="NET", action="append", default=[],
                     help="a network whose clients may log in and sign over TLS besides "
                          "this machine, e.g. 10.1.0.0/16 (repeatable); over plain HTTP "
                          "passwords are taken from this machine only")
    srv.add_argument("--server-name", metavar="NAME", action="append", default=[],
                     help="a name desks reach the station by (the Host header is checked; "
                          "the TLS certificate names it), repeatable")


def _absolute(url: str) -> str:
    """A relative SQLite path is relative to where `bench serve` was started."""
    prefix = "sqlite:///"
    if url.startswith(prefix) and not url[len(prefix):].startswith("/"):
        return prefix + str(Path(url[len(prefix):]).resolve())
    return url


def register_settings(args: argparse.Namespace) -> tuple[str | None, str | None]:
    """The register URL and the lab file: --register, else the lab file's `register:`
    (--lab FILE, else $BENCH_LAB_SETTINGS). Both given must name one register: signing
    issues through the lab file's register, and logging in through another would let one
    register's accounts sign into the other."""
    from bench.app import labfile
    from bench.app.station.signing import same_register
    from bench.core.lab import LabError, load_lab

    url = getattr(args, "register", None)
    try:     # one rule for the lab file: --lab, else $BENCH_LAB_SETTINGS; two differ: refuse
        chosen = labfile.for_command(getattr(args, "lab", None))
    except labfile.LabChoiceError as e:
        raise SystemExit(f"bench serve: {e}") from None
    lab_file = str(chosen) if chosen else None
    lab_url = None
    if lab_file:
        if not Path(lab_file).is_file():
            raise SystemExit(f"bench serve: lab file {lab_file}: not found")
        try:
            lab_url = load_lab(lab_file).register_url
        except LabError as e:
            raise SystemExit(f"bench serve: {e}") from None
        lab_file = str(Path(lab_file).resolve())
    url = _absolute(url) if url else lab_url
    if url and lab_url and not same_register(url, lab_url):
        raise SystemExit(f"bench serve: --register {url} is not the register the lab file "
                         f"{lab_file} names ({lab_url}): a draft signed here is issued "
                         "through the lab file's register, so both must name one")
    return url, lab_file


def settings_from_args(args: argparse.Namespace) -> tuple[StationSettings, bool]:
    """The settings, and whether the token was made up here (then it is printed)."""
    import secrets

    from bench.app.station.settings import StationSettings, is_loopback

    token = args.token or os.environ.get(TOKEN_ENV) or ""
    if not is_loopback(args.host) and args.host != "localhost" and not token:
        raise SystemExit(f"bench serve: --host {args.host} is reachable from other machines; "
                         f"set a token (--token or {TOKEN_ENV}) first")
    made = not token
    url, lab_file = register_settings(args)
    records = args.records
    if not records and lab_file:       # the lab file names the records too
        from bench.core.lab import LabError, load_lab
        try:
            records = load_lab(lab_file).records_url
        except LabError as e:
            raise SystemExit(f"bench serve: {e}") from None
    cert, key, nets = tls_settings(args)
    others = tuple(Path(d) for d in getattr(args, "other_runs", None) or ())
    for d in others:
        if not d.is_dir():
            raise SystemExit(f"bench serve: --other-runs {d}: not a folder")
    return StationSettings(runs=Path(args.runs), token=token or secrets.token_urlsafe(16),
                           host=args.host, port=args.port, records_url=records,
                           register_url=url, lab_file=lab_file,
                           trusted_proxy=getattr(args, "trusted_proxy", None),
                           tls_cert=cert, tls_key=key, password_networks=nets,
                           server_names=tuple(getattr(args, "server_name", None) or ()),
                           other_runs=others), made


def tls_settings(args: argparse.Namespace
                 ) -> tuple[Path | None, Path | None, tuple[str, ...]]:
    """The certificate and key (both or neither, each a readable PEM file that belongs to
    the other) and the password networks (only with TLS: over plain HTTP a password is
    taken from this machine alone)."""
    from bench.app.station.settings import LOOPBACK_NETWORKS, networks

    cert, key = getattr(args, "tls_cert", None), getattr(args, "tls_key", None)
    nets = tuple(getattr(args, "passwords_from", None) or ())
    if bool(cert) != bool(key):
        raise SystemExit("bench serve: --tls-cert and --tls-key go together (the certificate "
                         "and its private key)")
    if nets and not cert:
        raise SystemExit("bench serve: --passwords-from needs TLS (--tls-cert, --tls-key): "
                         "over plain HTTP passwords are taken from this machine only")
    try:
        networks(nets)
    except ValueError as e:
        raise SystemExit(f"bench serve: --passwords-from {e}") from None
    if not cert or not key:
        return None, None, LOOPBACK_NETWORKS
    ssl_context(Path(cert), Path(key))          # refuses here, naming what is wrong
    # this machine always, and the lab's networks it names
    return Path(cert).resolve(), Path(key).resolve(), \
        LOOPBACK_NETWORKS + tuple(n for n in nets if n not in LOOPBACK_NETWORKS)


def ssl_context(cert: Path, key: Path) -> ssl.SSLContext:
    """A server context (TLS 1.2 at least) with the certificate and key; SystemExit naming
    the file and what is wrong with it."""
    import ssl

    for what, f in (("--tls-cert", cert), ("--tls-key", key)):
        if not f.is_file():
            raise SystemExit(f"bench serve: {what} {f}: not found")
    ctx = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
    ctx.minimum_version = ssl.TLSVersion.TLSv1_2
    try:
        ctx.load_cert_chain(str(cert), str(key))
    except ssl.SSLError as e:
        said = ("the key is not the certificate's" if "KEY_VALUES_MISMATCH" in str(e)
                else f"not a PEM certificate and its key ({e.reason or e})")
        raise SystemExit(f"bench serve: --tls-cert {cert} / --tls-key {key}: {said}") from None
    except OSError as e:
        raise SystemExit(f"bench serve: --tls-cert {cert} / --tls-key {key}: {e}") from None
    return ctx


def cmd_serve(args: argparse.Namespace) -> int:
    from bench.app.station.app import create_app

    try:
        settings, made = settings_from_args(args)
    except SystemExit as e:
        print(e, file=sys.stderr)
        return 2
    app = create_app(settings)
    if settings.tls_cert is not None and settings.tls_key is not None:
        tls = _tls_server(app, settings.host, settings.port, settings.tls_cert,
                          settings.tls_key)
        tls.prepare()
        bound = tls.bind_addr
        port = bound[1] if isinstance(bound, tuple) else settings.port
        scheme, run, close = "https", tls.serve, tls.stop
    else:
        from waitress import create_server

        # the forwarding headers reach the app, which trusts them from --trusted-proxy
        # alone (signing.py) and refuses a password a proxy relays over plain HTTP; by
        # default waitress drops them, and with them the trusted proxy's X-Forwarded-For
        plain = create_server(app, host=settings.host, port=settings.port, threads=THREADS,
                              ident="ratebench-station", clear_untrusted_proxy_headers=False)
        port = plain.effective_port
        scheme, run, close = "http", plain.run, plain.close
    shown = f"[{settings.host}]" if ":" in settings.host else settings.host
    print(f"Station view of {settings.runs.resolve()} on {scheme}://{shown}:{port}/",
          flush=True)
    _say_settings(settings, made)
    try:
        run()
    except KeyboardInterrupt:
        pass
    finally:
        close()
    return 0


def _tls_server(app: Flask, host: str, port: int, cert: Path, key: Path) -> wsgi.Server:
    """The station over TLS: cheroot with its builtin adapter (Python's ssl module, TLS 1.2
    at least). A plain HTTP request to its port is not answered."""
    from cheroot import wsgi
    from cheroot.ssl.builtin import BuiltinSSLAdapter

    # at stop, an open live page's stream is cut after 1 s (the pages only read)
    server = wsgi.Server((host, port), app, numthreads=THREADS,
                         server_name="ratebench-station", shutdown_timeout=1)
    adapter = BuiltinSSLAdapter(str(cert), str(key))
    adapter.context = ssl_context(cert, key)
    server.ssl_adapter = adapter
    return server


def _say_settings(settings: StationSettings, made: bool) -> None:
    """What the station was started with, after the line saying where it listens."""
    from bench.app.register import redact

    lines = [
        f"Log in and sign at /login: accounts of register {redact(settings.register_url)}"
        if settings.register_url else
        "No lab register (--register URL or --lab FILE): read-only, no signing",
        f"TLS: certificate {settings.tls_cert}; passwords accepted from "
        f"{', '.join(settings.password_networks)}" if settings.tls else
        "Plain HTTP: passwords accepted from this machine only (127.0.0.1, ::1)",
        *(f"Also reading the runs folder {f.resolve()}" for f in settings.other_runs)]
    if made:
        lines.append(f"Stop-request token for this session: {settings.token} "
                     f"(set --token or {TOKEN_ENV} to choose one)")
    print("\n".join(lines), flush=True)
