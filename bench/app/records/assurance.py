"""Where measurement assurance meets a run: its start, its certificate, its authorisation.

- `warn_at_start`: an instrument of this stand out of control is warned on the console
  (and journaled by the caller) before anything moves; the run goes on.
- `write_assurance`: before the certificate is rendered, each instrument's status, with
  this run's own check values on its charts, goes to RUN_DIR/assurance.json; the
  certificate's traceability section prints it (`certificate_notes`).
- `assurance_refusals(run_dir, records_url)`: what `bench authorise` must refuse on: one
  text per instrument out of control with no review covering its signal (the rule named),
  empty when the certificate may be issued. It refreshes assurance.json first, so the
  certificate issued next states the status and the review as they are now.

None of these fails a run: a records database that cannot be read is warned about and
the certificate says the assurance was not assessed (authorise refuses then: a status
nobody could read is no status).
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable, Sequence
from pathlib import Path

import msgspec

from bench.app.db import redact
from bench.app.records.assurance_notes import ASSURANCE_FILE, CLAUSE
from bench.app.records.codec import (
    Assurance,
    InstrumentLine,
    ReviewLine,
    add_sim_run_number,
    read_assurance_file,
    read_records_meta,
    write_assurance_file,
)
from bench.app.records.control import (
    OUT_OF_CONTROL,
    InstrumentStatus,
    instrument_status,
)
from bench.app.records.extract import NotARun, record_of
from bench.app.records.hooks import RecordsTarget, target
from bench.app.records.store import CheckPoint, Records, RecordsError
from bench.core import rundir_layout as layout
from bench.core.config import Config, SimSettings, StandSettings
from bench.core.simbench import with_sim
from bench.core.simdrift import drifted, has_drift, stated_run_number
from bench.report.result_frame import ResultFrame

Warn = Callable[[str], None]


def _aware(t: dt.datetime | None) -> dt.datetime | None:
    return None if t is None else t.replace(tzinfo=dt.UTC)


def run_statuses(run_path: Path, url: str, frame: ResultFrame | None = None
                 ) -> list[InstrumentStatus]:
    """The status of each instrument this run rests on, from the records and this run's
    own check values (registered or not), with no point later than this run."""
    record = record_of(run_path, frame)
    when = _aware(record.date_utc)
    extra = [CheckPoint(record.uid, record.run_dir, record.serial, when, c,
                        simulated=record.simulated) for c in record.checks]
    out = []
    with Records.open(url) as rec:
        for serial in dict.fromkeys(c.serial for c in record.checks):
            s = instrument_status(rec, serial, [e for e in extra if e.check.serial == serial],
                                  through=when)
            if s is not None:
                out.append(s)
    return out


def _line(s: InstrumentStatus) -> InstrumentLine:
    r = s.last_review
    return InstrumentLine(
        serial=s.serial, role=s.role, model=s.model, state=s.state, runs=s.runs,
        rule=s.rule, line=s.line, open_signals=tuple(g.line for g in s.open_signals),
        reviewed_signals=tuple(g.line for g in s.reviewed_signals),
        last_review=None if r is None else ReviewLine(
            utc=r.utc.isoformat(), reviewer=r.reviewer, text=r.text,
            through_utc=r.through_utc.isoformat() if r.through_utc else None))


def write_assurance(run_path: Path, where: RecordsTarget | str, warn: Warn,
                    frame: ResultFrame | None = None) -> list[InstrumentStatus] | None:
    """RUN_DIR/assurance.json for the certificate; None (and a note in the file) when the
    records could not be read."""
    url = where.url if isinstance(where, RecordsTarget) else where
    doc = Assurance(records=redact(url), assessed_utc=dt.datetime.now(dt.UTC).isoformat())
    statuses: list[InstrumentStatus] | None
    try:
        statuses = run_statuses(run_path, url, frame)
        doc = msgspec.structs.replace(doc, instruments=tuple(_line(s) for s in statuses))
    except NotARun as e:
        doc = msgspec.structs.replace(doc, error=str(e))
        statuses = None
    except Exception as e:  # noqa: BLE001 - never fail a run over its records
        warn(f"records: measurement assurance not assessed ({e})")
        doc = msgspec.structs.replace(doc, error=str(e))
        statuses = None
    write_assurance_file(run_path / ASSURANCE_FILE, doc)
    return statuses


def assurance_lines(statuses: Sequence[InstrumentStatus]) -> list[str]:
    """One line per instrument for the certificate: in control, out of control with the
    rule, or not enough history with the count; and any review."""
    return [f"{CLAUSE}, {s.line}." for s in statuses]


def refusals_of(statuses: Sequence[InstrumentStatus]) -> list[str]:
    return [f"{s.name} is {OUT_OF_CONTROL}: {s.open_signals[0].line}; a review must be "
            f"recorded first: bench control {s.serial} --review 'WHO: why'"
            for s in statuses if s.state == OUT_OF_CONTROL]


def assurance_refusals(run_dir: str | Path, records_url: str | None = None) -> list[str]:
    """Why `bench authorise RUN_DIR` must refuse (empty: it may issue).

    `records_url` None means what `bench analyze` uses (lab settings, else records.sqlite
    beside the run). Refreshes RUN_DIR/assurance.json, so the certificate rendered next
    states each instrument's status and any review recorded since the run."""
    path = Path(run_dir)
    copy = path / layout.LAB          # a run's own command: the lab file it copied
    where = target(path.parent, records_url, lab_file=copy if copy.is_file() else None)
    problems: list[str] = []
    statuses = write_assurance(path, where, problems.append)
    if statuses is None:
        doc = read_assurance_file(path / ASSURANCE_FILE)
        error = doc.error if doc is not None and doc.error else problems
        return [f"{CLAUSE} cannot be assessed ({error}); the certificate cannot state it"]
    return refusals_of(statuses)


def warn_at_start(stand: StandSettings, where: RecordsTarget, warn: Warn
                  ) -> list[str]:
    """At a run's start: warn about each instrument of this stand that is out of control
    (its checks came from runs of this table, or the stand states its serial)."""
    serial = stand.identity.serial
    stated = {i.serial for a in stand.axes.values() for i in (a.drive, a.counter, a.fog)
              if i is not None and i.serial}
    if where.url.startswith("sqlite:///") and \
            not Path(where.url.removeprefix("sqlite:///")).exists():
        return []       # no records yet: nothing to warn about, nothing to create
    texts = []
    try:
        with Records.open(where.url) as rec:
            for inst in rec.instruments():
                pts = rec.checks(inst.serial)
                if inst.serial not in stated and not any(p.table_serial == serial
                                                         for p in pts):
                    continue
                s = instrument_status(rec, inst.serial, simulated=stand.simulated)
                if s is not None and s.state == OUT_OF_CONTROL:
                    texts.append(f"WARNING: {s.name} is OUT OF CONTROL: "
                                 f"{s.open_signals[0].line}; a certificate resting on it "
                                 f"cannot be issued until a review is recorded (bench "
                                 f"control {s.serial} --review 'WHO: why')")
    except RecordsError as e:
        warn(f"records: cannot check the instruments' control status: {e}")
        return []
    for t in texts:
        warn(t)
    return texts


def drifting_config(cfg: Config, run_path: Path, where: RecordsTarget, say: Warn) -> Config:
    """The run's config with a drifting twin's truth for this run (bench/core/simdrift.py).

    The run number is `sim.run_number`, else 1 + the runs of this table in the records;
    it is kept in meta.json, so a --resume drifts the same way as the first session."""
    stand_settings = cfg.stand_settings
    if not has_drift(stand_settings):
        return cfg
    meta_path = run_path / layout.META
    meta = read_records_meta(meta_path)
    number = (meta.sim_run_number if meta is not None else None) or \
        stated_run_number(stand_settings)
    if number is None:
        serial = stand_settings.identity.serial
        try:
            with Records.open(where.url) as rec:
                number = 1 + len([r for r in rec.runs(serial) if r.run_dir != run_path.name])
        except RecordsError as e:
            say(f"records: cannot count this table's runs ({e}); the twins drift as run 1")
            number = 1
    if meta is not None and meta.sim_run_number is None:
        add_sim_run_number(meta_path, int(number))
    sim, notes = drifted(stand_settings.sim or SimSettings(), int(number))
    for n in notes:
        say(n)
    return with_sim(cfg, axes=sim.axes)
