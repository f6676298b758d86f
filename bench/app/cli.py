"""The `bench` command (CONTRACT §1). Each subcommand lives in its own module.

The parser is built from light modules only (this one, bench/app/parsers.py,
bench/app/dcc/command.py, bench/app/station/serve.py), and a command's module is imported
when the command runs: `bench --help`, `bench --version` and a wrong option answer at once,
without numpy, the certificate or the databases (tests/test_cli_imports.py).
"""

from __future__ import annotations

import argparse
import logging
import os
import sys

import bench
from bench.app.dcc.command import COMMANDS as DCC_COMMANDS
from bench.app.dcc.command import add_parsers as add_dcc_parsers
from bench.app.parsers import (
    RECORDS_COMMAND_NAMES,
    add_authorise_parser,
    add_records_parsers,
    add_register_parser,
)
from bench.app.station.serve import add_serve_arguments

EPILOG = """\
examples:
  bench init mylab                       commented stand, procedure and lab files
  bench validate mylab/procedure.yaml    every problem of both files, file:line: key
  bench plan mylab/procedure.yaml        steps, bench time, raw data volume
  bench run mylab/procedure.yaml --yes   run; prints the run directory last
  bench run --example demo --yes         the shipped demo on its simulated twins
  bench run --resume runs/RUN_DIR        continue an interrupted run
  bench serve --runs runs                the station page at http://127.0.0.1:8765/

exit status:
  0  completed and every check passed
  1  completed and some check failed (the certificate says which)
  2  the input is invalid, or the runs folder has no room for the raw data (nothing
     was moved)
  3  aborted by a fault or by the operator (axes stopped, data kept; --resume works)

reference (all installed with the package):
  bench schema stand                     every key of a file: type, unit, default, meaning
                                         (also: bench schema procedure KIND, bench schema lab)
  bench init DIR                         commented files that validate, to start from
  bench method                           the measurement method every certificate cites
                                         (bench method --path: where it is installed)
"""


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="bench",
        description="Attest rotary rate tables: run YAML procedures on real instruments "
                    "or on their simulated twins, and issue a certificate.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"bench (ratebench) {bench.__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_run_parser(sub)
    _add_file_parsers(sub)
    _add_tool_parsers(sub)
    _add_impact_parser(sub)
    add_dcc_parsers(sub)
    add_authorise_parser(sub)
    add_records_parsers(sub)
    add_register_parser(sub)
    return p


def _add_run_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`bench run` (bench/app/commands.py runs it)."""
    run = sub.add_parser("run", help="run a procedure; prints the run directory last",
                         description="Run a procedure on its stand (twins if the stand has "
                         "a sim: block, or with --sim) and write a run directory; its path "
                         "is the last line printed. Examples: bench run p.yaml --yes; bench "
                         "run --resume runs/RUN_DIR. Exit 0 passed, 1 a check failed, 2 "
                         "invalid input or no room for the raw data (nothing moved), 3 "
                         "aborted (axes stopped, data kept, --resume continues).")
    run.add_argument("procedure", nargs="?", help="procedure YAML file")
    run.add_argument("--sim", action="store_true", help="run every instrument as its twin")
    run.add_argument("--out", default="runs", help="folder for the run directory (runs/)")
    run.add_argument("--yes", action="store_true", help="answer operator prompts with yes")
    run.add_argument("--resume", metavar="RUN_DIR", help="continue an interrupted run")
    run.add_argument("--example", metavar="NAME",
                     help="run a procedure shipped inside the package (demo, drift-demo)")
    run.add_argument("--records", metavar="URL",
                     help="records database (default: the lab file's records:, else "
                          "records.sqlite in the --out folder)")
    run.add_argument("--lab", metavar="FILE",
                     help="the lab file (register: and records:; default: the procedure's "
                          "certificate: {lab: FILE}, else $BENCH_LAB_SETTINGS; a --resume "
                          "uses the run's copy; two that differ refuse)")
    state = run.add_mutually_exclusive_group()
    state.add_argument("--as-found", dest="calibration_state", action="store_const",
                       const="as-found", help="this run measures the table as found")
    state.add_argument("--as-left", dest="calibration_state", action="store_const",
                       const="as-left", help="this run measures the table as left (adjusted)")
    run.add_argument("--adjustment", metavar="NOTE", help="what was adjusted since as-found")
    run.add_argument("--operator", metavar="ACCOUNT",
                     help="the performer's account in the lab register, authenticated "
                          "with its password before anything moves (without it the "
                          "certificate says the performer was not recorded)")
    run.add_argument("--password-stdin", action="store_true",
                     help="read the --operator account's password from standard input")
    _console_options(run)


def _add_file_parsers(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The commands on the configuration files: `validate`, `plan`, `schema`, `init`."""
    val = sub.add_parser("validate", help="check procedure and stand files; exit 2 on problems",
                         description="Check a procedure file and the stand file it names "
                         "(or a stand file alone) and print every problem at once, each "
                         "with file:line and key path. Exit 0 valid, 2 invalid.")
    val.add_argument("procedure", metavar="FILE",
                     help="a procedure YAML file (its stand is checked with it), or a "
                          "stand YAML file alone")
    plan = sub.add_parser("plan", help="print the steps, bench time and data volume",
                          description="Print the steps the run will take, the estimated "
                          "bench time and the raw data it will write; touches no "
                          "hardware. Exit 0, or 2 when the files are invalid.")
    plan.add_argument("procedure", metavar="PROCEDURE",
                      help="the procedure YAML file (its stand file is read too)")
    plan.add_argument("--out", default="runs", metavar="DIR",
                      help="the runs folder whose free space is compared (runs/)")
    sch = sub.add_parser("schema", help="configuration reference: every key of a file",
                         description="The configuration reference, generated from the "
                         "schema bench validate checks with: key, type, unit, default, "
                         "meaning, whether required. Examples: bench schema stand; "
                         "bench schema procedure KIND --json; bench schema lab")
    sch.add_argument("target", nargs="?", choices=("stand", "procedure", "lab"),
                     default="stand", help="which file (stand)")
    sch.add_argument("kind", nargs="?", metavar="KIND",
                     help="the procedure kind, for procedure (without it: the kinds "
                          "installed)")
    sch.add_argument("--json", action="store_true", help="print a JSON Schema instead")
    sch.add_argument("--markdown", action="store_true",
                     help="print docs/configuration.md (every file)")
    ini = sub.add_parser("init", help="write commented stand, procedure and lab files",
                         description="Write stand.yaml, procedure.yaml and lab.yaml, "
                         "commented, that validate: on the twins (runs at once), or with "
                         "--real for a real bench. Never overwrites (exit 2).")
    ini.add_argument("dir", nargs="?", default=".", help="folder to write into (.)")
    ini.add_argument("--real", action="store_true",
                     help="a real bench: no sim: block, the keys hardware needs")
    ini.add_argument("--kind", metavar="KIND",
                     help="the procedure kind whose files to write (default: the first "
                          "installed kind that offers starter files)")


def _add_tool_parsers(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The commands around a run: `analyze`, `devices`, `decode`, `serve`, `sim`, `method`."""
    ana = sub.add_parser("analyze", help="recompute result.json and certificate from raw data")
    ana.add_argument("run_dir")
    ana.add_argument("--records", metavar="URL",
                     help="records database (default: the run's lab file's records:, else "
                          "records.sqlite beside the run)")
    ana.add_argument("--lab", metavar="FILE",
                     help="the lab file (default: the run's copy; one that differs refuses)")
    ana.add_argument("--reason", metavar="TEXT",
                     help="why the run is analysed again (the lab register records it with "
                          "the new result)")
    _console_options(ana)
    dev = sub.add_parser("devices", help="open each instrument, print its identity")
    dev.add_argument("stand")
    dev.add_argument("--sim", action="store_true", help="open the twins instead")
    dec = sub.add_parser("decode", help="decode a raw FOG capture")
    dec.add_argument("raw_file")
    dec.add_argument("--format", required=True, dest="fmt", help="frame format, e.g. kvh-a")
    dec.add_argument("--csv", help="write the samples to this CSV file")
    dec.add_argument("--first-index", type=int, default=None, metavar="N",
                     help="the capture's first sample index (default: from the run's "
                          "events for a file in a run directory, else 0)")
    srv = sub.add_parser("serve", help="local web station view: live runs and records")
    add_serve_arguments(srv)
    sim = sub.add_parser("sim", help="start the stand's twins alone; print their addresses")
    sim.add_argument("stand", help="stand YAML file")
    met = sub.add_parser("method", help="print the measurement method the certificates cite",
                         description="Print the method text this installation ships "
                         "(bench/method.md, the project's docs/method.md), which every "
                         "certificate cites by its SHA-256.")
    met.add_argument("--path", action="store_true", help="print where the file is instead")


def _add_impact_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`bench impact` (bench/app/impact.py runs it)."""
    imp = sub.add_parser(
        "impact", help="what an item found out of tolerance did to the runs that used it",
        description="Find every run the lab register holds that used the item since its "
        "last calibration found in tolerance, analyse each one's raw captures again (from "
        "the --runs folders) with the item's as-found error applied as a correction, and "
        "report each figure's shift in its unit and over its U, and each conformity "
        "outcome that changes; runs whose raw data is not found are listed. Records an "
        "audit entry 'impact assessed' (a quality account). Exit 0 assessed, 2 refused.")
    imp.add_argument("serial", metavar="SERIAL", help="the item's serial in the inventory")
    imp.add_argument("--register", metavar="URL", help="the lab register")
    imp.add_argument("--lab", metavar="FILE", help="the lab file naming the register")
    imp.add_argument("--runs", metavar="DIR", nargs="+", action="extend",
                     help="folders holding run folders (each searched two levels down)")
    imp.add_argument("--json", metavar="FILE", help="write the report as JSON too")
    imp.add_argument("--report", metavar="DIR",
                     help="write the report as JSON, PDF and HTML in DIR, with a draft "
                     "notification per customer (text and HTML)")
    imp.add_argument("--as", dest="as_account", required=True, metavar="ACCOUNT",
                     help="the quality account assessing (its password is asked)")
    imp.add_argument("--password-stdin", action="store_true",
                     help="read the password from standard input")


def _console_options(cmd: argparse.ArgumentParser) -> None:
    """How the run is shown: a live display on a terminal, plain lines otherwise."""
    shown = cmd.add_mutually_exclusive_group()
    shown.add_argument("--quiet", action="store_true",
                       help="print only faults, warnings, prompts and the verdict")
    shown.add_argument("--log-json", action="store_true",
                       help="progress and summary as JSON lines on standard error")


def main(argv: list[str] | None = None) -> int:
    try:
        return _main(argv)
    except BrokenPipeError:
        # `bench schema stand | head`: the reader left; say nothing more (Python's
        # documented recipe: point stdout at devnull so the exit flush cannot fail)
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0


def _main(argv: list[str] | None) -> int:
    # canopen logs an SDO abort it sends as a warning; without a handler Python prints it
    # to stderr above our own message, and the first line the operator reads would be a
    # library's echo of the cause, not the cause (the session reports every fault itself)
    logging.getLogger("canopen").addHandler(logging.NullHandler())
    args = build_parser().parse_args(argv)
    command = args.command
    if command == "decode":
        from bench.app.decode import decode_command
        return decode_command(args.raw_file, args.fmt, args.csv, args.first_index)
    if command == "serve":
        from bench.app.station.serve import cmd_serve
        return cmd_serve(args)
    if command == "schema":
        from bench.app.reference import schema_command
        return schema_command(args.target, args.kind, args.json, args.markdown)
    if command == "init":
        from bench.app.starter import init_command
        return init_command(args.dir, args.real, args.kind)
    if command == "method":
        from bench.app.reference import method_command
        return method_command(args.path)
    if command == "sim":
        from bench.app.simserve import serve
        return serve(args.stand)
    if command in RECORDS_COMMAND_NAMES:
        from bench.app.records.commands import RECORDS_COMMANDS
        return RECORDS_COMMANDS[command](args)
    if command == "register":
        from bench.app.register.commands import cmd_register
        return cmd_register(args)
    if command == "impact":
        from bench.app.impact import cmd_impact
        return cmd_impact(args)
    if command == "authorise":
        from bench.app.certificate.authorise import cmd_authorise
        return cmd_authorise(args)
    if command in DCC_COMMANDS:
        return DCC_COMMANDS[command](args)
    from bench.app.commands import dispatch
    return dispatch(args)


if __name__ == "__main__":
    sys.exit(main())
