"""The `bench` subcommands: validate, plan, run (and --resume), analyze, devices.

Exit status (CONTRACT §1): 0 completed and every check passed; 1 completed and some
check failed; 2 the input is invalid (nothing was moved); 3 aborted by a fault or by the
operator (the axes were stopped, the data kept, `--resume` works).
"""

from __future__ import annotations

import argparse
import datetime as dt
import os
import sys
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bench import __version__
from bench import certificate as certificates
from bench.certificate.model import Document
from bench.config import Config, ConfigError
from bench.console import PlainConsole, open_console
from bench.dcc.command import write_run_dcc
from bench.devices import list_devices
from bench.diskspace import data_volume_lines, expected_raw_bytes, space_problem
from bench.engine import Abort, Engine, RunContext, SignalGuard
from bench.examples import example_path
from bench.instruments import StandClaimError, StopErrors, check_references
from bench.journal import RunDir
from bench.lab import lab_path
from bench.loader import is_stand_file, load_config, load_stand
from bench.plan import format_duration
from bench.records.assurance import drifting_config, warn_at_start, write_assurance
from bench.records.hooks import (
    RecordsTarget,
    history_sections,
    mark_run,
    register_run,
    target,
    warn_if_overdue,
)
from bench.registry import procedure_kind
from bench.simbench import for_session
from bench.summary import Summary, summarize
from bench.traceability import overdue, overdue_warning
from bench.yamlfile import YamlError, load_yaml
from drivers.axis import NOT_STOPPED
from drivers.clock import MonotonicClock

EXIT_PASS, EXIT_FAIL, EXIT_INVALID, EXIT_ABORTED = 0, 1, 2, 3


def _err(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def _load(procedure: str, stand: str | Path | None = None) -> Config | None:
    try:
        return load_config(procedure, stand)
    except ConfigError as e:
        _err(f"{len(e.problems)} problem(s); nothing was started:")
        for p in e.problems:
            _err(f"  {p}")
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
            _err(f"{len(e.problems)} problem(s):")
            for p in e.problems:
                _err(f"  {p}")
            return EXIT_INVALID
        print(f"stand {args.procedure}: valid (procedures naming it are checked against "
              "it by bench validate PROCEDURE.yaml)")
        return EXIT_PASS
    cfg = _load(args.procedure)
    if cfg is None:
        return EXIT_INVALID
    print(f"{cfg.procedure_path}: valid {cfg.kind} procedure; stand {cfg.stand_path}: valid")
    for note in getattr(procedure_kind(cfg.kind), "notes", lambda _c: [])(cfg):
        print(f"note: {note}")
    return EXIT_PASS


def cmd_plan(args: argparse.Namespace) -> int:
    cfg = _load(args.procedure)
    if cfg is None:
        return EXIT_INVALID
    plan = procedure_kind(cfg.kind).build_plan(cfg)
    print("\n".join(plan.lines()))
    print("\n".join(data_volume_lines(cfg.stand_settings, _plan_axes(cfg, plan), plan.total_s,
                                      Path(args.out))))
    return EXIT_PASS


def _plan_axes(cfg: Config, plan: Any) -> list[str]:
    """The stand axes the plan's steps use (their instruments record while it runs)."""
    return sorted({st.axis for st in plan.steps if st.axis and st.axis in cfg.stand_settings.axes})


def _room_for(cfg: Config, plan: Any, folder: Path) -> str | None:
    """Why the runs folder cannot hold the plan's raw data, or None."""
    return space_problem(folder, expected_raw_bytes(cfg.stand_settings, _plan_axes(cfg, plan),
                                                    plan.total_s))


def _write_outputs(run: RunDir, cfg: Config, progress: PlainConsole,
                   records: RecordsTarget | None = None
                   ) -> tuple[dict[str, Any], Document | None]:
    """result.json, then the certificate (PDF, HTML, DCC); returns the result and the
    certificate's document (None when it could not be written: a run that leaves no
    certificate must not exit as if it had, nor one whose DCC does not validate)."""
    result = procedure_kind(cfg.kind).analyze(run, cfg)
    run.write_json("result.json", result)
    # the table's history from the records, when they hold any (never fails the run)
    history = history_sections(run.path, result, records, progress.warn) if records else []
    if records:   # each instrument's control status, for the traceability section
        write_assurance(run.path, records, progress.warn, result)
    try:
        documents: list[Document] = []
        for path in certificates.write_certificate(run, result, documents=documents,
                                                   extra_sections=history):
            progress.line(f"wrote {path}")
        doc = documents[-1]
    except Exception as e:  # noqa: BLE001 - result.json stands; say what is missing
        traceback.print_exc(file=sys.stderr)            # a bug to report: keep its trace
        progress.warn(f"the certificate could not be written: {e!r}; result.json is in "
                      f"{run.path}; once fixed, `bench analyze {run.path}` writes it")
        return result, None
    if not write_run_dcc(run.path, result, cfg.stand_settings.dcc, progress.line, warn=progress.warn):
        return result, None
    return result, doc


def _summary(result: dict[str, Any], doc: Document | None) -> Summary:
    """The certificate's figures; without a certificate, only the verdict."""
    if doc is not None:
        return summarize(doc)
    return Summary((), (), "", str(result.get("verdict", "incomplete")).upper())


def cmd_run(args: argparse.Namespace) -> int:
    if args.resume:
        try:
            run = RunDir(args.resume)
        except FileNotFoundError as e:
            _err(str(e))
            return EXIT_INVALID
        cfg = _load(str(run.procedure_file), run.stand_file)
    else:
        procedure = args.procedure
        if getattr(args, "example", None):
            if procedure:
                _err("bench run: give a PROCEDURE.yaml or --example NAME, not both")
                return EXIT_INVALID
            try:
                procedure = str(example_path(args.example))
            except KeyError as e:
                _err(f"bench run --example: {e.args[0]}")
                return EXIT_INVALID
        if not procedure:
            _err("bench run: give a PROCEDURE.yaml, --example NAME, or --resume RUN_DIR")
            return EXIT_INVALID
        cfg = _load(procedure)
        run = None
    if cfg is None:
        return EXIT_INVALID
    if run is None:
        short = _room_for(cfg, procedure_kind(cfg.kind).build_plan(cfg), Path(args.out))
        if short:   # before the run directory exists: nothing written, nothing moved
            _err(f"Not started: {short}")
            return EXIT_INVALID
        run = RunDir.create(args.out, cfg.procedure_path, cfg.stand_path,
                            lab_path(cfg.procedure_path, dict(cfg.common.certificate)))
        mark_run(run.path, cfg.common, args.calibration_state, args.adjustment,
                 args.operator)
    console = open_console(quiet=args.quiet, log_json=args.log_json)
    status = run_session(cfg, run, sim=args.sim, yes=args.yes, resume=bool(args.resume),
                         progress=console, records=args.records)
    print(run.path)
    return status


SimHook = Callable[[Any], None]


def run_session(cfg: Config, run: RunDir, *, sim: bool = False, yes: bool = False,
                resume: bool = False, progress: PlainConsole | None = None,
                on_sim_started: SimHook | None = None, records: str | None = None) -> int:
    """One session of a run (the first, or a --resume): returns the exit status.

    Whatever happens inside, the axes are stopped, the instruments closed, what was
    measured is analyzed, and the run directory is left ready for `--resume`. At its end
    the run is registered in the records (`records` URL, default records.sqlite in the
    runs folder); a records database that cannot be reached only warns.
    """
    progress = progress or open_console()
    where = target(run.path.parent, records, progress.warn)
    table_overdue = warn_if_overdue(cfg.stand_settings.identity, where, progress.warn)
    out_of_control = warn_at_start(cfg.stand_settings, where, progress.warn)
    kind = procedure_kind(cfg.kind)
    plan = kind.build_plan(cfg)
    done = run.completed_units()
    todo = plan.remaining(done)
    if resume:  # finer than the unit where the kind keeps parts (a rate ladder's halves)
        todo = kind.resume_plan(todo, run)
    short = _room_for(cfg, todo, run.path)
    if short:
        _err(f"Not started: {short}")
        print(f"Free some space, then: bench run --resume {run.path}")
        return EXIT_INVALID
    simbench = None
    stand = cfg.stand_settings
    status = EXIT_ABORTED
    # one rule for the whole session: the first cause is what the operator reads; what
    # goes wrong later, while stopping, is added beneath it and never replaces it
    cause: str | None = None
    later: list[str] = []
    with SignalGuard(progress.line) as guard:
        bench = None
        engine_ran = False
        try:
            if sim or cfg.has_sim:
                progress.line("Starting the simulated bench (twins on real channels)...")
                sim_cfg = drifting_config(cfg, run.path, where, progress.line)
                if resume:  # the twins' noise of this session, not a replay of the first
                    sim_cfg = for_session(sim_cfg, run.next_session())
                simbench, stand = kind.start_sim(sim_cfg)
                clock: Any = simbench.clock
            else:
                clock = MonotonicClock()
            run.begin_session(clock.now)
            run.event("session_start", resume=resume, sim=simbench is not None,
                      done_units=done, clock_speed=clock.speed, argv=sys.argv[1:],
                      version=__version__, prompts="--yes" if yes else "operator",
                      pid=os.getpid())
            for t in overdue(cfg.stand_settings, dt.datetime.now(dt.UTC).date()):
                progress.line(overdue_warning(t))
                run.event("calibration_overdue", where=t.where, item=t.item,
                          certificate=t.certificate, due=t.due.isoformat() if t.due else None)
            if table_overdue:
                run.event("records_overdue", text=table_overdue)
            for text in out_of_control:
                run.event("out_of_control", text=text)
            bench = kind.open_bench(cfg, stand, clock, run)
            for ax in bench.axes.values():
                run.event("identity", axis=ax.name, **ax.identities,
                          **({"counter_reference": ax.reference_text}
                             if ax.reference_text else {}))
            if simbench is not None:
                simbench.start_clock()
                if on_sim_started is not None:
                    on_sim_started(simbench)
            check_references(bench)
            progress.line(f"Run directory: {run.path}")
            if done:
                progress.line(f"Resuming: {len(done)} unit(s) already done: {', '.join(done)}")
            progress.line(f"{len(todo.steps)} steps, estimated bench time "
                          f"{format_duration(todo.total_s)}")
            for w in todo.warnings:
                progress.warn(f"Warning: {w}")
            ctx = RunContext(cfg, clock, bench, run, progress, yes=yes)
            t0 = time.monotonic()
            engine_ran = True
            Engine(ctx, kind.execute).run(todo, guard)
            run.event("completed", wall_s=time.monotonic() - t0)
            status = EXIT_PASS
        except StandClaimError as e:  # raised while opening: no axis was commanded yet
            guard.stopping = True
            _err(f"Refused: {cfg.stand_path}: {e}")
            later += _journal(run, "refused", reason=str(e))
            status = EXIT_INVALID
        except BaseException as e:  # noqa: BLE001 - whatever it is, the stop follows
            guard.stopping = True
            status = EXIT_ABORTED
            later += list(getattr(e, "__notes__", []))
            if isinstance(e, Abort) and engine_ran:   # the engine stopped and journaled it
                cause = str(e)
            else:
                phase = "while running" if engine_ran else "while setting up the bench"
                cause = f"{phase}: {e or type(e).__name__}"
                if bench is not None:
                    later += bench.stop_and_close(progress.line)
                    bench = None
                later += _journal(run, "abort", reason=str(e) or type(e).__name__,
                                  error=type(e).__name__)
            if not isinstance(e, Exception | KeyboardInterrupt):
                raise  # SystemExit and the like: the finally below still stops the bench
        finally:
            guard.stopping = True
            progress.close()
            if bench is not None:
                try:
                    bench.close()
                except StopErrors as e:
                    later += e.errors
                except Exception as e:  # noqa: BLE001
                    later.append(f"closing the instruments: {e}")
            if simbench is not None:
                try:
                    simbench.stop()
                except Exception as e:  # noqa: BLE001
                    later.append(f"stopping the simulated bench: {e}")
        if later:
            status = EXIT_ABORTED  # something may not have stopped: never a clean exit
            cause = cause or "the run completed, but stopping the bench failed"
        if cause is not None:
            progress.warn(f"Aborted: {cause}")
            for note in dict.fromkeys(n.removeprefix("also, while stopping: ") for n in later):
                progress.warn(f"  also, while stopping: {note}")
        doc: Document | None = None
        result = None
        guard.writing = True  # the axes are stopped: Ctrl-C now leaves the writing
        try:
            if status != EXIT_INVALID:  # a refused stand measured nothing: nothing to issue
                result, doc = _write_outputs(run, cfg, progress, where)
        except KeyboardInterrupt as e:
            progress.warn(f"{e or 'interrupted'}: the axes were already stopped; result.json "
                          f"and the certificate may be missing or from an earlier session: "
                          f"`bench analyze {run.path}` writes them from the raw data")
            result = None
            status = EXIT_ABORTED
            cause = cause or "interrupted while writing the outputs"
        except Exception as e:  # noqa: BLE001 - the raw data is kept whatever happens
            progress.warn(f"analysis failed: {e!r}; the raw data is in {run.path}; "
                          f"fix and run `bench analyze {run.path}`")
            result = None
            status = EXIT_ABORTED  # no verdict without an analysis
        guard.writing = False
        if result is not None:
            progress.summary(_summary(result, doc))
            if status == EXIT_PASS and result.get("verdict") == "fail":
                status = EXIT_FAIL
            if status == EXIT_PASS and result.get("verdict") == "incomplete":
                status = EXIT_ABORTED
        if status in (EXIT_PASS, EXIT_FAIL) and doc is None:
            status = EXIT_ABORTED  # measured, but nothing to sign: not a completed run
        elif status == EXIT_ABORTED:
            stopped = ("AN AXIS COULD NOT BE TOLD TO STOP (above): check the table first"
                       if any(NOT_STOPPED in n for n in later) else "the axes were stopped")
            print(f"The run was aborted; {stopped}. Continue with: "
                  f"bench run --resume {run.path}")
        if run.session:
            for err in _journal(run, "exit", status=status, cause=cause, later=later):
                _err(f"  also: {err}")
        try:
            run.close()
        except Exception as e:  # noqa: BLE001
            _err(f"  also: closing the event log: {e}")
    if result is not None:
        register_run(run.path, where, progress.warn, result)
    return status


def _journal(run: RunDir, kind: str, **fields: Any) -> list[str]:
    """An event written on the stop path: a failure to write it is reported, not raised."""
    if not run.session:
        return []
    try:
        run.event(kind, **fields)
    except Exception as e:  # noqa: BLE001 - e.g. a full disk: say so, keep stopping
        return [f"the {kind} event could not be journaled: {e}"]
    return []


def cmd_analyze(args: argparse.Namespace) -> int:
    try:
        run = RunDir(args.run_dir)
    except FileNotFoundError as e:
        _err(str(e))
        return EXIT_INVALID
    cfg = _load(str(run.procedure_file), run.stand_file)
    if cfg is None:
        return EXIT_INVALID
    console = open_console(quiet=args.quiet, log_json=args.log_json)
    where = target(run.path.parent, args.records, console.warn)
    result, doc = _write_outputs(run, cfg, console, where)
    register_run(run.path, where, console.warn, result)
    console.summary(_summary(result, doc))
    print(run.path / "result.json")
    if doc is None:
        return EXIT_ABORTED
    return {"pass": EXIT_PASS, "fail": EXIT_FAIL}.get(str(result.get("verdict")),
                                                      EXIT_ABORTED)


def cmd_devices(args: argparse.Namespace) -> int:
    return list_devices(args.stand, sim=args.sim)


def dispatch(args: argparse.Namespace) -> int:
    return {"validate": cmd_validate, "plan": cmd_plan, "run": cmd_run,
            "analyze": cmd_analyze, "devices": cmd_devices}[args.command](args)
