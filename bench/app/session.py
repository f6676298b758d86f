"""One session of a run (the first, or a `--resume`): the object that owns it.

Everything a session opens (the twins, the instruments, the analysis worker) registers
its own stop with the session's registry as it is opened (bench/core/stops.py), and
every path out, a completed run, a fault, Ctrl-C or a refusal, leaves through `_stop`:
the registry run once, last opened first (the worker; each axis ramped down, else quick
stop, then disabled: drivers/axis.py safe_stop; the instruments and raw logs closed; the
twins stopped). One rule for what the operator reads: the first cause; the outcomes of
the stops that failed are listed beneath it and never replace it (python-can's
`BusABC.shutdown` and Bluesky's `finalize_wrapper` are the models).
"""

from __future__ import annotations

import datetime as dt
import gc
import os
import sys
import time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from bench import __version__
from bench.app import certificate as certificates
from bench.app.certificate.figures import started_early
from bench.app.console import PlainConsole, open_console
from bench.app.dcc.command import write_run_dcc
from bench.app.names import resume_command
from bench.app.records.assurance import drifting_config, warn_at_start, write_assurance
from bench.app.records.hooks import (
    RecordsTarget,
    history_sections,
    register_run,
    target,
    warn_if_overdue,
)
from bench.app.summary import Summary, summarize
from bench.core import events as ev
from bench.core import rundir_layout as layout
from bench.core.config import Config, StandSettings
from bench.core.diskspace import expected_raw_bytes, space_problem
from bench.core.engine import Abort, Engine, Interrupted, RunContext, SignalGuard
from bench.core.instruments import (
    STOPPING_NOTE,
    Bench,
    StandClaimError,
    check_references,
    identity_record,
)
from bench.core.journal import RunDir
from bench.core.plan import Plan, format_duration
from bench.core.registry import procedure_kind
from bench.core.simbench import SimBench, for_session
from bench.core.stops import StopOutcome, Stops, attempt
from bench.core.traceability import identity_mismatches, overdue, overdue_warning
from bench.report.certificate.model import Document
from bench.report.certificate.sources import Sources
from bench.report.codec import KindResult, ResultPart
from drivers.clock import Clock, MonotonicClock

EXIT_PASS, EXIT_FAIL, EXIT_INVALID, EXIT_ABORTED = 0, 1, 2, 3

SimHook = Callable[[SimBench], None]


def err(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def plan_axes(cfg: Config, plan: Plan) -> list[str]:
    """The stand axes the plan's steps use (their instruments record while it runs)."""
    return sorted({st.axis for st in plan.steps if st.axis and st.axis in cfg.stand_settings.axes})


def room_for(cfg: Config, plan: Plan, folder: Path) -> str | None:
    """Why the runs folder cannot hold the plan's raw data, or None."""
    return space_problem(folder, expected_raw_bytes(cfg.stand_settings, plan_axes(cfg, plan),
                                                    plan.total_s))


@dataclass(frozen=True)
class Outputs:
    """What the analysis of a session wrote: the result as the analysis gave it (result.json
    is its encoding; the certificate's, the DCC's and the records' writers take it), its
    verdict, and the certificate's document (None when it could not be written: a run
    that leaves no certificate must not exit as if it had, nor one whose DCC does not
    validate)."""

    result: KindResult[ResultPart]
    verdict: str | None
    doc: Document | None


def write_outputs(run: RunDir, cfg: Config, progress: PlainConsole,
                  records: RecordsTarget | None = None) -> Outputs:
    """result.json, then the certificate (PDF, HTML, DCC).
    What the analysis opens registers its stop here (`bench run` and `bench analyze`
    alike), run once it ends, however it ends."""
    stops = Stops()
    try:
        with stops.collecting():
            return _write_outputs(run, cfg, progress, records)
    finally:
        for outcome in stops.run():
            if not outcome.ok:
                progress.warn(f"  also, while stopping: {outcome.text}")


def _write_outputs(run: RunDir, cfg: Config, progress: PlainConsole,
                   records: RecordsTarget | None) -> Outputs:
    result = procedure_kind(cfg.kind).analysis.analyze(run, cfg)
    # result.json is the result's encoding (bench/report/codec.py); the certificate, the
    # DCC, the records and the register take the result itself: nothing reads it back
    run.write_json(layout.RESULT, result.document)
    src = Sources.analysed(result, run.path)
    verdict = result.verdict
    # the table's history from the records, when they hold any (never fails the run)
    history = history_sections(run.path, result.frame, records, progress.warn) \
        if records else []
    if records:   # each instrument's control status, for the traceability section
        write_assurance(run.path, records, progress.warn, result.frame)
    try:
        documents: list[Document] = []
        for path in certificates.write_certificate(run, src, documents=documents,
                                                   extra_sections=history):
            progress.line(f"wrote {path}")
        doc = documents[-1]
    except Exception as e:  # noqa: BLE001 - result.json stands; say what is missing
        traceback.print_exc(file=sys.stderr)            # a bug to report: keep its trace
        progress.warn(f"the certificate could not be written: {e!r}; result.json is in "
                      f"{run.path}; once fixed, `bench analyze {run.path}` writes it")
        return Outputs(result, verdict, None)
    if not write_run_dcc(run.path, src, cfg.stand_settings.dcc, progress.line, warn=progress.warn):
        return Outputs(result, verdict, None)
    return Outputs(result, verdict, doc)


def summary_of(outputs: Outputs) -> Summary:
    """The certificate's figures; without a certificate, only the verdict."""
    if outputs.doc is not None:
        return summarize(outputs.doc, outputs.result.frame)
    return Summary((), (), "", (outputs.verdict or "incomplete").upper())


class RunSession:
    """A session of a run: `run()` returns the exit status (CONTRACT §1).

    Whatever happens inside, the axes are stopped, the instruments closed, what was
    measured is analyzed, and the run directory is left ready for `--resume`. At its end
    the run is registered in the records (`records` URL, default records.sqlite in the
    runs folder); a records database that cannot be reached only warns.
    """

    def __init__(self, cfg: Config, run: RunDir, *, sim: bool = False, yes: bool = False,
                 resume: bool = False, progress: PlainConsole | None = None,
                 on_sim_started: SimHook | None = None, records: str | None = None,
                 performer: Mapping[str, str | None] | None = None) -> None:
        self.cfg, self.run_dir, self.sim, self.yes, self.resume = cfg, run, sim, yes, resume
        #: the account the register authenticated for this session (`--operator`), or None
        self.performer = dict(performer) if performer else None
        self.progress = progress or open_console()
        self.on_sim_started = on_sim_started
        # the run's own lab file: the copy it made when it started (bench/app/labfile.py)
        copy = run.path / layout.LAB
        self.where = target(run.path.parent, records, self.progress.warn,
                            lab_file=copy if copy.is_file() else None)
        self.kind = procedure_kind(cfg.kind)
        self.status = EXIT_ABORTED
        self.cause: str | None = None       # the first cause: what the operator reads
        #: every stop of the session, registered as its resource is opened; their
        #: outcomes, typed, go beneath the first cause
        self.stops = Stops()
        #: what the first cause's exception notes (e.g. an instrument's recovery), said
        #: beneath it as before; the stops' own failures come from their outcomes
        self._notes: list[str] = []
        self.bench: Bench | None = None
        self.simbench: SimBench | None = None
        self.engine_ran = False
        self.unsigned = False

    # -- the session, start to end -------------------------------------------------
    def run(self) -> int:
        """The session, delivered to the lab's server as it goes when the records are one
        (bench/app/fleet: in the background, never failing the run; once more at its end)."""
        # what the command has made so far (its modules, the configuration) lives as long
        # as the session: out of the collector's sight while it runs, its full collections
        # walk only what the session makes (issue 62: a demo's 5 full collections took
        # 1.1-1.4 s of CPU, on the stepping thread too, and 0.7-0.8 s so), and back after
        # it, so a process running sessions one after another (the tests) frees as before
        gc.freeze()
        try:
            return self._delivered()
        finally:
            gc.unfreeze()

    def _delivered(self) -> int:
        from bench.app.fleet.live_run import delivered, report_lost

        report_lost(self.run_dir.path.parent, self.where, self.cfg.stand_settings.bench_name,
                    self.progress.warn)
        with delivered(self.run_dir, self.where, self.cfg.stand_settings.bench_name,
                       self.progress.warn, err):
            return self._run()

    def _run(self) -> int:
        table_overdue = warn_if_overdue(self.cfg.stand_settings.identity, self.where, self.progress.warn)
        out_of_control = warn_at_start(self.cfg.stand_settings, self.where, self.progress.warn)
        plan = self.kind.plan.build_plan(self.cfg)
        done = self.run_dir.completed_units()
        todo = plan.remaining(done)
        if self.resume:  # finer than the unit where the kind keeps parts (a ladder's halves)
            todo = self.kind.plan.resume_plan(todo, self.run_dir)
        short = room_for(self.cfg, todo, self.run_dir.path)
        if short:
            err(f"Not started: {short}")
            print(f"Free some space, then: {resume_command(self.run_dir.path, self.yes)}")
            return EXIT_INVALID
        outputs: Outputs | None = None
        # the certificate's figure workers start now, with the kind's figures loaded (its
        # package's certificate module, imported there, not here: none, nothing loaded)
        package = type(self.kind).__module__.rpartition(".")[0]
        early = started_early((f"{package}.certificate",) if package else ())
        with early, SignalGuard(self.progress.line) as guard, self.stops.collecting():
            try:
                self._measure(guard, todo, done, table_overdue, out_of_control)
                guard.check()             # a signal lost where it landed (SignalGuard)
                self.status = EXIT_PASS
            except StandClaimError as e:  # raised while opening: no axis commanded yet
                guard.stopping = True
                guard.received()
                err(f"Refused: {self.cfg.stand_path}: {e}")
                self._journal(ev.Refused(reason=str(e)))
                self.status = EXIT_INVALID
            except BaseException as e:  # noqa: BLE001 - whatever it is, the stop follows
                guard.stopping = True
                guard.received()
                self._failed(e)
                if not isinstance(e, Exception | KeyboardInterrupt | Interrupted):
                    raise  # SystemExit and the like: the finally below still stops
            finally:
                guard.stopping = True
                self._stop()
            self._report_cause()
            outputs = self._write(guard)
            self._finish()
        if outputs is not None:
            register_run(self.run_dir.path, self.where, self.progress.warn,
                         outputs.result.frame)
        return self.status

    def _measure(self, guard: SignalGuard, todo: Plan, done: list[str],
                 table_overdue: str | None, out_of_control: list[str]) -> None:
        cfg, run, progress = self.cfg, self.run_dir, self.progress
        stand = cfg.stand_settings
        if self.sim or cfg.has_sim:
            progress.line("Starting the simulated bench (twins on real channels)...")
            sim_cfg = drifting_config(cfg, run.path, self.where, progress.line)
            if self.resume:  # the twins' noise of this session, not a replay of the first
                sim_cfg = for_session(sim_cfg, run.next_session())
            # its twins' stops are registered with the session's as they start
            self.simbench, stand = self.kind.steps.start_sim(sim_cfg)
        clock: Clock = self.simbench.clock if self.simbench is not None else MonotonicClock()
        run.begin_session(clock.now)
        run.write(ev.SessionStarted(
            resume=self.resume, sim=self.simbench is not None, done_units=done,
            clock_speed=clock.speed, argv=sys.argv[1:], version=__version__,
            prompts="--yes" if self.yes else "operator", pid=os.getpid(),
            performer=self.performer, os_user=_os_user()))
        for t in overdue(cfg.stand_settings, dt.datetime.now(dt.UTC).date()):
            progress.line(overdue_warning(t))
            run.write(ev.CalibrationOverdue(where=t.where, item=t.item,
                                            certificate=t.certificate,
                                            due=t.due.isoformat() if t.due else None))
        if table_overdue:
            run.write(ev.RecordsOverdue(text=table_overdue))
        for text in out_of_control:
            run.write(ev.OutOfControl(text=text))
        # each instrument's stop registered with the session's as it is opened
        self.bench = bench = self.kind.steps.open_bench(cfg, stand, clock, run)
        for ax in bench.axes.values():
            run.write(identity_record(ax))
        if self.simbench is not None:
            self.simbench.start_clock()
            if self.on_sim_started is not None:
                self.on_sim_started(self.simbench)
        check_references(bench)
        self._check_identities(stand, bench, run, progress)
        progress.line(f"Run directory: {run.path}")
        if done:
            progress.line(f"Resuming: {len(done)} unit(s) already done: {', '.join(done)}")
        progress.line(f"{len(todo.steps)} steps, estimated bench time "
                      f"{format_duration(todo.total_s)}")
        for w in todo.warnings:
            progress.warn(f"Warning: {w}")
        ctx = RunContext(cfg, clock, bench, run, progress, yes=self.yes, stops=self.stops)
        t0 = time.monotonic()
        self.engine_ran = True
        Engine(ctx, self.kind.steps.execute).run(todo, guard)
        run.write(ev.Completed(wall_s=time.monotonic() - t0))

    def _check_identities(self, stand: StandSettings, bench: Bench, run: RunDir,
                          progress: PlainConsole) -> None:
        """The serials the stand states against those the instruments report, before
        anything moves. On a real stand a mismatch refuses the run (exit 2): another
        instrument than the stand file's is connected, and its check values would land
        on the stated one's control chart. On twins it is a finding, stated on the
        console and the certificate, and changes neither verdict nor exit status."""
        found = identity_mismatches(stand, {a: ax.identities for a, ax in bench.axes.items()})
        if not found:
            return
        if self.simbench is None:
            raise StandClaimError(
                "; ".join(m.text for m in found) + ": another instrument than the stand "
                "file names is connected (correct the serial in the stand file, or connect "
                "the instrument it names)")
        for m in found:
            run.write(ev.IdentityMismatch(where=m.where, stated=m.stated,
                                          reported=m.reported, query=m.query))
            progress.warn(f"FINDING: {m.text}; on twins the run goes on (a real stand "
                          "would be refused)")

    # -- the one stop path ---------------------------------------------------------
    def _failed(self, e: BaseException) -> None:
        """The first cause; a failure outside the engine also stops the axes here (the
        engine stops and journals its own)."""
        self.status = EXIT_ABORTED
        self._notes = [n for n in getattr(e, "__notes__", [])
                       if not n.startswith(STOPPING_NOTE)]   # those are outcomes
        if isinstance(e, Abort) and self.engine_ran:
            self.cause = str(e)
            return
        phase = "while running" if self.engine_ran else "while setting up the bench"
        self.cause = f"{phase}: {e or type(e).__name__}"
        if self.bench is not None:
            self.stops.record(*self.bench.safe_stop(self.progress.line))
        self._journal(ev.Aborted(reason=str(e) or type(e).__name__, error=type(e).__name__))

    def _stop(self) -> None:
        """The console first (its live display ends), then every registered stop, last
        opened first: the worker, the instruments (each axis stopped, then closed), the
        twins. Safe twice: an axis already stopped after a failure stops at once."""
        self.progress.close()
        self.stops.run()
        if self.later:
            self.status = EXIT_ABORTED  # something may not have stopped: never clean
            self.cause = self.cause or "the run completed, but stopping the bench failed"

    @property
    def later(self) -> list[str]:
        """Beneath the first cause: its own notes, then every stop that failed, each once,
        in the order it happened (the exit event's `later`)."""
        return list(dict.fromkeys([*self._notes, *(o.text for o in self.stops.failures)]))

    def _report_cause(self) -> None:
        if self.cause is None:
            return
        self.progress.warn(f"Aborted: {self.cause}")
        for note in self.later:
            self.progress.warn(f"  also, while stopping: {note}")

    def _journal(self, record: ev.Event) -> StopOutcome | None:
        """An event written on the stop path: a failure to write it is an outcome among
        the stops', not raised."""
        if not self.run_dir.session:
            return None
        outcome = attempt(f"journaling the {record.kind} event",
                          lambda: self.run_dir.write(record), "journal")
        self.stops.record(outcome)
        return outcome

    # -- after the stop: outputs and exit ------------------------------------------
    def _write(self, guard: SignalGuard) -> Outputs | None:
        """result.json and the certificate (never for a refused stand: nothing was
        measured). Ctrl-C now only ends the writing: the axes are already stopped."""
        run, progress = self.run_dir, self.progress
        outputs: Outputs | None = None
        guard.writing = True
        try:
            if self.status != EXIT_INVALID:
                outputs = write_outputs(run, self.cfg, progress, self.where)
            guard.check()                 # a Ctrl-C lost where it landed (SignalGuard)
        except (KeyboardInterrupt, Interrupted) as e:  # the latter: a second signal
            guard.received()
            progress.warn(f"{e or 'interrupted'}: the axes were already stopped; result.json "
                          f"and the certificate may be missing or from an earlier session: "
                          f"`bench analyze {run.path}` writes them from the raw data")
            outputs = None
            self.status = EXIT_ABORTED
            self.cause = self.cause or "interrupted while writing the outputs"
        except Exception as e:  # noqa: BLE001 - the raw data is kept whatever happens
            progress.warn(f"analysis failed: {e!r}; the raw data is in {run.path}; "
                          f"fix and run `bench analyze {run.path}`")
            outputs = None
            self.status = EXIT_ABORTED  # no verdict without an analysis
        guard.writing = False
        if outputs is not None:
            progress.summary(summary_of(outputs))
            if self.status == EXIT_PASS and outputs.verdict == "fail":
                self.status = EXIT_FAIL
            if self.status == EXIT_PASS and outputs.verdict == "incomplete":
                self.status = EXIT_ABORTED
        if self.status in (EXIT_PASS, EXIT_FAIL) and (outputs is None or outputs.doc is None):
            self.status = EXIT_ABORTED  # measured, but nothing to sign: not completed
            self.unsigned = True        # (said above; a resume would not help)
        return outputs

    def _finish(self) -> None:
        run = self.run_dir
        if self.status == EXIT_ABORTED and not self.unsigned:
            stopped = ("AN AXIS COULD NOT BE TOLD TO STOP (above): check the table first"
                       if self.stops.axis_moving else "the axes were stopped")
            print(f"The run was aborted; {stopped}. Continue with: "
                  f"{resume_command(run.path, self.yes)}")
        if run.session:
            outcome = self._journal(ev.Exited(status=self.status, cause=self.cause,
                                              later=self.later))
            if outcome is not None and not outcome.ok:
                err(f"  also: {outcome.text}")
        try:
            run.close()
        except Exception as e:  # noqa: BLE001
            err(f"  also: closing the event log: {e}")


def _os_user() -> str | None:
    import getpass
    try:
        return getpass.getuser()
    except (KeyError, OSError):
        return None


def run_session(cfg: Config, run: RunDir, *, sim: bool = False, yes: bool = False,
                resume: bool = False, progress: PlainConsole | None = None,
                on_sim_started: SimHook | None = None, records: str | None = None,
                performer: Mapping[str, str | None] | None = None) -> int:
    """One session of a run (`bench run`, `bench run --resume`): its exit status."""
    return RunSession(cfg, run, sim=sim, yes=yes, resume=resume, progress=progress,
                      on_sim_started=on_sim_started, records=records,
                      performer=performer).run()
