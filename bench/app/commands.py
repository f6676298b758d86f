"""The `bench` subcommands: validate, plan, run (and --resume), analyze, devices.

Exit status (CONTRACT §1): 0 completed and every check passed; 1 completed and some
check failed; 2 the input is invalid (nothing was moved); 3 aborted by a fault or by the
operator (the axes were stopped, the data kept, `--resume` works).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from bench.app import labfile
from bench.core import rundir_layout as layout
from bench.core.config import Config, ConfigError
from bench.core.loader import is_stand_file, load_config, load_stand
from bench.core.placeholders import left_to_fill, placeholder_notes
from bench.core.registry import procedure_kind
from bench.core.yamlfile import YamlError, load_yaml

# `bench validate` imports the loader only: the session, the console, the records and the
# certificate are imported by the commands that plan, run or analyze (bench/app/cli.py)
if TYPE_CHECKING:
    from bench.app.register.gate import StartFacts, StartGate
    from bench.app.session import run_session
    from bench.core.config import Config

__all__ = ["EXIT_ABORTED", "EXIT_FAIL", "EXIT_INVALID", "EXIT_PASS", "dispatch", "run_session"]

#: bench.app.session's exit statuses (CONTRACT §1)
EXIT_PASS, EXIT_FAIL, EXIT_INVALID, EXIT_ABORTED = 0, 1, 2, 3


def __getattr__(name: str) -> object:
    """`run_session`, for the tests and benchmarks that run a session in-process; loaded
    on first use, with the session."""
    if name == "run_session":
        from bench.app.session import run_session
        return run_session
    raise AttributeError(f"module 'bench.app.commands' has no attribute {name!r}")


def err(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def _load(procedure: str, stand: str | Path | None = None) -> Config | None:
    try:
        return load_config(procedure, stand)
    except ConfigError as e:
        err(f"{len(e.problems)} problem(s); nothing was started:")
        for p in e.problems:
            err(f"  {p}")
        return None


def cmd_validate(args: argparse.Namespace) -> int:
    try:
        alone = is_stand_file(load_yaml(args.procedure))
    except YamlError:
        alone = False        # load_config reports it
    if alone:
        try:
            load_stand(args.procedure)
        except ConfigError as e:
            err(f"{len(e.problems)} problem(s):")
            for p in e.problems:
                err(f"  {p}")
            return EXIT_INVALID
        print(f"stand {args.procedure}: valid (procedures naming it are checked against "
              "it by bench validate PROCEDURE.yaml)")
        for note in placeholder_notes(args.procedure):
            print(f"note: {note}")
        return EXIT_PASS
    cfg = _load(args.procedure)
    if cfg is None:
        return EXIT_INVALID
    print(f"{cfg.procedure_path}: valid {cfg.kind} procedure; stand {cfg.stand_path}: valid")
    for note in [*placeholder_notes(cfg.procedure_path, cfg.stand_path),
                 *procedure_kind(cfg.kind).settings.notes(cfg)]:
        print(f"note: {note}")
    return EXIT_PASS


def cmd_plan(args: argparse.Namespace) -> int:
    from bench.app.session import plan_axes
    from bench.core.diskspace import data_volume_lines

    cfg = _load(args.procedure)
    if cfg is None:
        return EXIT_INVALID
    plan = procedure_kind(cfg.kind).plan.build_plan(cfg)
    print("\n".join(plan.lines()))
    print("\n".join(data_volume_lines(cfg.stand_settings, plan_axes(cfg, plan), plan.total_s,
                                      Path(args.out))))
    return EXIT_PASS


def cmd_run(args: argparse.Namespace) -> int:
    from bench.app.console import open_console
    from bench.app.records.hooks import mark_run
    from bench.app.session import room_for, run_session
    from bench.core.journal import RunDir
    from bench.core.lab import lab_path
    from bench.examples import example_path

    if args.resume:
        try:
            run = RunDir(args.resume)
        except FileNotFoundError as e:
            err(str(e))
            return EXIT_INVALID
        cfg = _load(str(run.procedure_file), run.stand_file)
        if cfg is None:
            return EXIT_INVALID
        # a resume is a session of the run: its performer too is authenticated by the
        # run's register, before anything moves (and audited)
        from bench.app.records.extract import run_uid

        gate = _admitted("Not resumed", lambda: labfile.for_run(run.path, args.lab), cfg,
                         args, run_uid(run.meta, run.path.name), run.next_session())
        if gate is None:
            return EXIT_INVALID
    else:
        procedure = args.procedure
        if getattr(args, "example", None):
            if procedure:
                err("bench run: give a PROCEDURE.yaml or --example NAME, not both")
                return EXIT_INVALID
            try:
                procedure = str(example_path(args.example))
            except KeyError as e:
                err(f"bench run --example: {e.args[0]}")
                return EXIT_INVALID
        if not procedure:
            err("bench run: give a PROCEDURE.yaml, --example NAME, or --resume RUN_DIR")
            return EXIT_INVALID
        cfg = _load(procedure)
        run = None
    if cfg is None:
        return EXIT_INVALID
    if run is None:
        short = room_for(cfg, procedure_kind(cfg.kind).plan.build_plan(cfg), Path(args.out))
        if short:   # before the run directory exists: nothing written, nothing moved
            err(f"Not started: {short}")
            return EXIT_INVALID
        left = [] if cfg.has_sim or args.sim else left_to_fill(cfg.procedure_path,
                                                                cfg.stand_path)
        if left:    # only twins run on values left out (bench/core/placeholders.py)
            err(f"Not started: a real stand runs once nothing is left to fill in; "
                f"{len(left)} key(s) are:")
            for line in left:
                err(f"  {line}")
            return EXIT_INVALID
        named = lab_path(cfg.procedure_path, dict(cfg.common.certificate))
        # before the run directory exists: nothing written, nothing moved
        import uuid

        uid = uuid.uuid4().hex      # the run's, before its folder: the register names it
        gate = _admitted("Not started", lambda: _new_run_lab(args, named), cfg, args, uid)
        if gate is None:
            return EXIT_INVALID
        run = RunDir.create(args.out, cfg.procedure_path, cfg.stand_path, gate.lab_file,
                            run_uid=uid)
        mark_run(run.path, cfg.common, args.calibration_state, args.adjustment,
                 gate.meta())
    console = open_console(quiet=args.quiet, log_json=args.log_json)
    status = run_session(cfg, run, sim=args.sim, yes=args.yes, resume=bool(args.resume),
                         progress=console, records=args.records,
                         performer=gate.performer if gate is not None else None)
    from bench.app.register.runs import deliver

    deliver(run.path, "session", err)   # the register holds what was measured (issue 54)
    print(run.path)
    return status


def _new_run_lab(args: argparse.Namespace, named: Path | None) -> Path | None:
    """A new run's lab file by the one rule; a lab.yaml left in the runs folder, which no
    command reads any more, refuses rather than let the run's records go elsewhere."""
    from bench.app.records.settings import stray_lab_file

    chosen = labfile.for_command(args.lab, named)
    stray = stray_lab_file(args.out) if chosen is None and not args.records else None
    if stray:
        raise labfile.LabChoiceError(stray)
    return chosen


class Admitted:
    """A session admitted to start: the lab file it runs under and the register's word."""

    def __init__(self, lab_file: Path | None, gate: StartGate) -> None:
        self.lab_file, self.gate = lab_file, gate
        self.performer = gate.performer

    def meta(self) -> StartFacts:
        return self.gate.meta()


def _admitted(verb: str, lab_of: Callable[[], Path | None], cfg: Config,
              args: argparse.Namespace, uid: str | None = None,
              session: int | None = None) -> Admitted | None:
    """Before anything moves: the lab file by the one rule (bench/app/labfile.py), the
    records it names, and the register's word on the performer and the stand's items;
    None (each reason said after `verb`) when the session may not start."""
    try:
        lab_file = lab_of()
    except labfile.LabChoiceError as e:
        err(f"{verb}: {e}")
        return None
    refusal = _records_refusal(lab_file, args.records)
    if refusal:
        err(f"{verb}: {refusal}")
        return None
    gate = _start_gate(lab_file, cfg, bool(cfg.has_sim or args.sim), args, uid, session)
    if gate.refusal:
        err(f"{verb}: the lab register refuses:")
        for line in gate.refusal:
            err(f"  {line}")
        return None
    return Admitted(lab_file, gate)


def _records_refusal(lab_file: Path | None, records: str | None) -> str | None:
    """Why a run may not start: its lab file names the lab's PostgreSQL records and
    --records would write elsewhere (its runs would be missing from the lab's page)."""
    if lab_file is None or not records:
        return None
    from bench.app.db import redact
    from bench.core.lab import LabError, load_lab
    try:
        named = load_lab(lab_file).records_url
    except LabError as e:
        return str(e)
    if named and named.startswith("postgresql") and named != records:
        return (f"the lab file {lab_file} names the records {redact(named)}; --records "
                f"{redact(records)} would write this run elsewhere: leave --records out")
    return None


def _start_gate(lab_file: Path | None, cfg: Config, simulated: bool,
                args: argparse.Namespace, uid: str | None = None,
                session: int | None = None) -> StartGate:
    """The lab register's word before anything moves (bench/app/register/gate.py); it
    records the run's start (or a resume's session) in the register (issue 54)."""
    import socket

    from bench.app.register import RegisterError
    from bench.app.register.credentials import Passwords
    from bench.app.register.gate import StartGate, start_gate
    from bench.app.register.runs import input_digests
    from bench.core.lab import LabError, load_lab
    from bench.core.traceability import traced_items

    try:
        url = load_lab(lab_file).register_url if lab_file else None
        pw = Passwords(bool(getattr(args, "password_stdin", False))) if args.operator \
            else None
        return start_gate(url, traced_items(cfg.stand_settings), simulated, args.operator,
                          pw.next if pw else _no_password, run_uid=uid,
                          bench=cfg.stand_settings.bench_name or socket.gethostname(),
                          inputs=input_digests(cfg.procedure_path, cfg.stand_path, lab_file),
                          session=session)
    except (LabError, RegisterError) as e:
        return StartGate([str(e)], None, [], None)


def _no_password(prompt: str) -> str:
    raise AssertionError(f"no performer to authenticate ({prompt})")


def cmd_analyze(args: argparse.Namespace) -> int:
    from bench.app.console import open_console
    from bench.app.records.hooks import register_run, target
    from bench.app.session import summary_of, write_outputs
    from bench.core.journal import RunDir

    try:
        run = RunDir(args.run_dir)
    except FileNotFoundError as e:
        err(str(e))
        return EXIT_INVALID
    cfg = _load(str(run.procedure_file), run.stand_file)
    if cfg is None:
        return EXIT_INVALID
    try:
        lab_file = labfile.for_run(run.path, getattr(args, "lab", None))
    except labfile.LabChoiceError as e:
        err(f"bench analyze: {e}")
        return EXIT_INVALID
    console = open_console(quiet=args.quiet, log_json=args.log_json)
    where = target(run.path.parent, args.records, console.warn, lab_file=lab_file)
    try:
        outputs = write_outputs(run, cfg, console, where)
    except ValueError as e:      # a run file the analysis refuses (a corrections file)
        console.close()
        err(f"bench analyze: not analysed: {e}")
        return EXIT_INVALID
    register_run(run.path, where, console.warn, outputs.result.frame)
    from bench.app.register.runs import deliver

    deliver(run.path, "analysis", console.warn,      # a new registered analysis of the uid
            getattr(args, "reason", None) or "bench analyze")
    console.summary(summary_of(outputs))
    print(run.path / layout.RESULT)
    if outputs.doc is None:
        return EXIT_ABORTED
    return {"pass": EXIT_PASS, "fail": EXIT_FAIL}.get(str(outputs.verdict), EXIT_ABORTED)


def cmd_devices(args: argparse.Namespace) -> int:
    from bench.app.devices import list_devices

    return list_devices(args.stand, sim=args.sim)


def dispatch(args: argparse.Namespace) -> int:
    return {"validate": cmd_validate, "plan": cmd_plan, "run": cmd_run,
            "analyze": cmd_analyze, "devices": cmd_devices}[args.command](args)
