"""The `bench` command (CONTRACT §1). Each subcommand lives in its own module."""

from __future__ import annotations

import argparse
import sys

import bench
from bench import commands
from bench.certificate.authorise import add_parser as add_authorise_parser
from bench.certificate.authorise import cmd_authorise
from bench.dcc.command import COMMANDS as DCC_COMMANDS
from bench.dcc.command import add_parsers as add_dcc_parsers
from bench.decode import decode_command
from bench.records.commands import RECORDS_COMMANDS
from bench.records.commands import add_parsers as add_records_parsers
from bench.station.serve import cmd_serve


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="bench",
        description="Attest rotary rate tables: run YAML procedures on real instruments "
                    "or on their simulated twins, and issue a certificate.")
    p.add_argument("--version", action="version", version=f"bench (ratebench) {bench.__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    run = sub.add_parser("run", help="run a procedure; prints the run directory last")
    run.add_argument("procedure", nargs="?", help="procedure YAML file")
    run.add_argument("--sim", action="store_true", help="run every instrument as its twin")
    run.add_argument("--out", default="runs", help="folder for the run directory (runs/)")
    run.add_argument("--yes", action="store_true", help="answer operator prompts with yes")
    run.add_argument("--resume", metavar="RUN_DIR", help="continue an interrupted run")
    run.add_argument("--example", metavar="NAME",
                     help="run a procedure shipped inside the package (demo, drift-demo)")
    run.add_argument("--records", metavar="URL",
                     help="records database (default records.sqlite in the --out folder)")
    state = run.add_mutually_exclusive_group()
    state.add_argument("--as-found", dest="calibration_state", action="store_const",
                       const="as-found", help="this run measures the table as found")
    state.add_argument("--as-left", dest="calibration_state", action="store_const",
                       const="as-left", help="this run measures the table as left (adjusted)")
    run.add_argument("--adjustment", metavar="NOTE", help="what was adjusted since as-found")
    run.add_argument("--operator", help="who runs it (default: the login name)")
    _console_options(run)
    val = sub.add_parser("validate", help="check procedure and stand files; exit 2 on problems")
    val.add_argument("procedure")
    plan = sub.add_parser("plan", help="print the steps and the estimated bench time")
    plan.add_argument("procedure")
    ana = sub.add_parser("analyze", help="recompute result.json and certificate from raw data")
    ana.add_argument("run_dir")
    ana.add_argument("--records", metavar="URL",
                     help="records database (default records.sqlite beside the run)")
    _console_options(ana)
    dev = sub.add_parser("devices", help="open each instrument, print its identity")
    dev.add_argument("stand")
    dev.add_argument("--sim", action="store_true", help="open the twins instead")
    dec = sub.add_parser("decode", help="decode a raw FOG capture")
    dec.add_argument("raw_file")
    dec.add_argument("--format", required=True, dest="fmt", help="frame format, e.g. kvh-a")
    dec.add_argument("--csv", help="write the samples to this CSV file")
    srv = sub.add_parser("serve", help="local web station view: live runs and records")
    srv.add_argument("--runs", default="runs", help="the runs folder to show (runs/)")
    srv.add_argument("--records", metavar="URL", help="records database URL")
    srv.add_argument("--port", type=int, default=8765, help="TCP port (8765; 0 picks one)")
    srv.add_argument("--host", default="127.0.0.1",
                     help="address to bind (127.0.0.1); another one needs --token")
    srv.add_argument("--token", help="token for stop requests and remote viewers "
                                     "(default: $BENCH_STATION_TOKEN, else one is made up)")
    add_dcc_parsers(sub)
    add_authorise_parser(sub)
    add_records_parsers(sub)
    return p


def _console_options(cmd: argparse.ArgumentParser) -> None:
    """How the run is shown: a live display on a terminal, plain lines otherwise."""
    shown = cmd.add_mutually_exclusive_group()
    shown.add_argument("--quiet", action="store_true",
                       help="print only faults, warnings, prompts and the verdict")
    shown.add_argument("--log-json", action="store_true",
                       help="progress and summary as JSON lines on standard error")


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.command == "decode":
        return decode_command(args.raw_file, args.fmt, args.csv)
    if args.command == "serve":
        return cmd_serve(args)
    if args.command in RECORDS_COMMANDS:
        return RECORDS_COMMANDS[args.command](args)
    if args.command == "authorise":
        return cmd_authorise(args)
    if args.command in DCC_COMMANDS:
        return DCC_COMMANDS[args.command](args)
    return commands.dispatch(args)


if __name__ == "__main__":
    sys.exit(main())
