"""Where a run meets the records: at its start (overdue?), in its certificate (history),
and at its end (registration).

None of these may fail a run: a records database that is absent, unreachable or broken
gives a warning, the run directory stays complete, and `bench records import RUNS_DIR`
registers the run later.
"""

from __future__ import annotations

import datetime as dt
import getpass
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from msgspec import UNSET

from bench.app.db import redact
from bench.app.records.codec import RunMarks, mark_meta_file
from bench.app.records.extract import STATES, NotARun, record_of
from bench.app.records.settings import LabSettings, SettingsError, load_lab_settings, records_url
from bench.app.records.store import Records, RecordsError
from bench.core import rundir_layout as layout
from bench.core.config import CommonSettings, Identity

if TYPE_CHECKING:
    from bench.app.register.gate import StartFacts
    from bench.report.certificate.model import Block
    from bench.report.result_frame import ResultFrame

Warn = Callable[[str], None]
IMPORT_HINT = "`bench records import {runs}` registers it once the database is back"


@dataclass(frozen=True)
class RecordsTarget:
    """Which database a run registers into, and the lab settings in force."""

    url: str
    settings: LabSettings
    runs_dir: Path

    def interval_for(self, serial: str, stand_days: int | None) -> int | None:
        return self.settings.interval_for(serial, stand_days)


def target(runs_dir: str | Path, url: str | None = None, warn: Warn | None = None,
           lab_file: str | Path | None = None) -> RecordsTarget:
    """--records URL, else lab settings, else RUNS_DIR/records.sqlite (CONTRACT §1).

    A broken lab settings file is warned about, not fatal, when a run is at stake."""
    try:
        settings = load_lab_settings(runs_dir, lab_file)
    except SettingsError as e:
        if warn is None:
            raise
        warn(f"records: {e}; using the defaults")
        settings = LabSettings()
    return RecordsTarget(records_url(runs_dir, url, settings), settings, Path(runs_dir))


def mark_run(run_path: Path, procedure: CommonSettings, state: str | None = None,
             note: str | None = None, register: StartFacts | None = None) -> None:
    """Write as-found/as-left, the adjustment note and the operator into meta.json.

    The CLI flag wins over the procedure key; written before the run starts so that an
    import years later reads what the operator said at the time."""
    state = state or procedure.calibration_state
    note = note or procedure.adjustment_note
    if state is not None and state not in STATES:
        raise ValueError(f"calibration state {state!r}: expected one of {', '.join(STATES)}")
    try:
        login = getpass.getuser()
    except (KeyError, OSError):
        login = None
    # the performer is an account the register authenticated (`bench run --operator`),
    # never a name from a file (issue 42); `operator` keeps who ran it for the records
    performer = register["performer"] if register else None
    account = performer.get("account") if performer else login
    mark_meta_file(run_path / layout.META, RunMarks(
        calibration_state=state, adjustment_note=note, os_user=login,
        operator=None if account is None else str(account),
        # the procedure file's word only
        operator_stated=procedure.operator if procedure.operator else UNSET), register or {})


def warn_if_overdue(ident: Identity, where: RecordsTarget, warn: Warn,
                    today: dt.date | None = None) -> str | None:
    """At a run's start: say so when this table is overdue; returns the warning text."""
    serial = ident.serial
    if not serial:
        return None
    try:
        with Records.open(where.url) as rec:
            items = rec.due(today=today, within_days=0, everything=True,
                            intervals=lambda s, d: where.interval_for(
                                s, d or ident.recertification_interval_days))
    except RecordsError as e:
        warn(f"records: cannot check the due date: {e}; the run goes on and is registered "
             f"when the database is back")
        return None
    item = next((i for i in items if i.table.serial == serial), None)
    if item is None or item.days_left is None or item.days_left >= 0:
        return None         # in time, or never passed (a first certification is no recall)
    last = item.table.last_certificate or "none"
    text = (f"WARNING: table {serial} is overdue for recertification by {-item.days_left} d "
            f"(due {item.due_date}; last certificate {last}, interval "
            f"{where.interval_for(serial, item.table.interval_days)} d)")
    warn(text)
    return text


def register_run(run_path: Path, where: RecordsTarget, warn: Warn,
                 frame: ResultFrame | None = None) -> str | None:
    """At a run's end (and after `bench analyze`): register it (its result's frame as the
    analysis gave it, else result.json's); None if that failed."""
    try:
        record = record_of(run_path, frame)
    except NotARun as e:
        warn(f"records: not registered: {e}")
        return None
    try:
        with Records.open(where.url) as rec:
            outcome = rec.register(record, where.interval_for(record.serial,
                                                              record.interval_days))
    except Exception as e:  # noqa: BLE001 - never fail a run over its records
        reason = e if isinstance(e, RecordsError) else f"{redact(where.url)}: {e!r}"
        warn(f"WARNING: records: the run was not registered ({reason}); the run "
             f"directory is complete; " + IMPORT_HINT.format(runs=where.runs_dir))
        return None
    return outcome


def history_sections(run_path: Path, frame: ResultFrame, where: RecordsTarget,
                     warn: Warn) -> list[tuple[str, tuple[Block, ...]]]:
    """The certificate's history section, or nothing (no earlier run, no database)."""
    from bench.app.records.section import history_section

    try:
        current = record_of(run_path, frame)
    except NotARun:
        return []
    try:
        with Records.open(where.url) as rec:
            return history_section(rec, current, redact(where.url))
    except Exception as e:  # noqa: BLE001 - the certificate is issued without its history
        warn(f"records: the certificate's history section was left out ({e})")
        return []
