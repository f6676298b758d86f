"""`bench serve`: the station view on a local port (waitress, a production WSGI server)."""

from __future__ import annotations

import argparse
import os
import secrets
import sys
from pathlib import Path

from bench.app.station.app import StationSettings, create_app, is_loopback

TOKEN_ENV = "BENCH_STATION_TOKEN"
THREADS = 16        # each open live page holds one thread for its event stream


def settings_from_args(args: argparse.Namespace) -> tuple[StationSettings, bool]:
    """The settings, and whether the token was made up here (then it is printed)."""
    token = args.token or os.environ.get(TOKEN_ENV) or ""
    if not is_loopback(args.host) and args.host != "localhost" and not token:
        raise SystemExit(f"bench serve: --host {args.host} is reachable from other machines; "
                         f"set a token (--token or {TOKEN_ENV}) first")
    made = not token
    return StationSettings(runs=Path(args.runs), token=token or secrets.token_urlsafe(16),
                           host=args.host, port=args.port, records_url=args.records), made


def cmd_serve(args: argparse.Namespace) -> int:
    from waitress import create_server

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
