"""`bench serve`: the station view on a local port (waitress, a production WSGI server)."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
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
    return StationSettings(runs=Path(args.runs), token=token or secrets.token_urlsafe(16),
                           host=args.host, port=args.port, records_url=records,
                           register_url=url, lab_file=lab_file,
                           trusted_proxy=getattr(args, "trusted_proxy", None)), made


def cmd_serve(args: argparse.Namespace) -> int:
    from waitress import create_server

    from bench.app.station.app import create_app

    try:
        settings, made = settings_from_args(args)
    except SystemExit as e:
        print(e, file=sys.stderr)
        return 2
    app = create_app(settings)
    server = create_server(app, host=settings.host, port=settings.port, threads=THREADS,
                           ident="ratebench-station")
    port = server.effective_port
    print(f"Station view of {settings.runs.resolve()} on http://{settings.host}:{port}/",
          flush=True)
    if settings.register_url:
        from bench.app.register import redact

        print(f"Log in and sign at /login: accounts of register "
              f"{redact(settings.register_url)}", flush=True)
    else:
        print("No lab register (--register URL or --lab FILE): read-only, no signing",
              flush=True)
    if made:
        print(f"Stop-request token for this session: {settings.token} "
              f"(set --token or {TOKEN_ENV} to choose one)", flush=True)
    try:
        server.run()
    except KeyboardInterrupt:
        pass
    finally:
        server.close()
    return 0
