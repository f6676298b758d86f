"""Lab records: every run in a database, each table's history, due dates.

A recertification is only half read without the table's past (is the rate error drifting
year over year, was the table adjusted, when is it due again?), so every run is
registered when it ends: the stand's identity, axis, procedure and its hash, dates,
operator, every reported figure with U (k = 2) and its check verdict, the certificate
number and the SHA-256 of the certificate files.

Where: `--records URL` (SQLAlchemy URL: `sqlite:///path`, `postgresql://user@host/db`),
else `records:` in the lab settings (`lab.yaml` in the runs folder, or
$BENCH_LAB_SETTINGS, the DCC's lab file; see
`settings.py`), else `records.sqlite` in the runs folder (CONTRACT §1). One code path for
SQLite and PostgreSQL (SQLAlchemy Core, `schema.py`); the schema is migrated by Alembic
at every open (`migrations/`, shipped in the package). A run never fails over its
records: it warns, and `bench records import RUNS_DIR` registers it later (idempotent).

Read API (for tools such as the web station view; every call opens no run directory):

    from bench.app.records import Records, target

    with Records.open(url) as rec:        # or Records.open(target(runs_dir).url)
        rec.tables()        -> [TableInfo]   serial, maker, model, location, interval_days,
                                             runs, last_run_utc, last_pass_utc,
                                             last_certificate
        rec.table(serial)   -> TableInfo | None
        rec.runs(serial)    -> [RunInfo]     oldest first: uid, kind, title, run_dir,
                                             run_path, date_utc, verdict, operator,
                                             calibration_state, adjustment_note,
                                             certificate_number, cert_files {name: sha256}
        rec.run(uid)        -> RunInfo | None
        rec.figures(uid)    -> [FigureRecord] axis, quantity, set_rate_dps, value, u (k = 2),
                                             unit, tolerance, verdict, rule
        rec.trend(serial, quantities=None) -> [TrendPoint]  (run_uid, date_utc,
                                             certificate_number, calibration_state, figure)
        rec.drafts(limit=50) -> [(serial, run_dir, verdict, date_utc, operator)]
                                             runs ended with a verdict, no certificate yet
        rec.due(today=None, within_days=30, intervals=None, everything=False) -> [DueItem]
                                             table, due_date, days_left (< 0: overdue),
                                             status text
    trend_png(points, title, figures) -> PNG bytes | None   (each figure the runs' kinds
                                             declare as trended, U bars, tolerance band)

Measurement assurance (ISO/IEC 17025 7.7; checks.py, control.py, assurance.py):

        rec.instruments()   -> [InstrumentInfo]  serial, role, model, first/last seen
        rec.checks(serial)  -> [CheckPoint]      run_uid, run_dir, table_serial, date_utc,
                                                 check (quantity, set_rate_dps, value, u, unit)
        rec.reviews(serial) -> [ReviewInfo]      utc, reviewer, text, status, through_utc
        rec.add_review(serial, reviewer, text, status, through_utc)
    control.instrument_status(rec, serial) -> InstrumentStatus  (state, line, series, signals)
    assurance.assurance_refusals(run_dir, records_url) -> [str]  (bench authorise)

Quantities (`FigureRecord.quantity`, unit in the name as in result.json): what the run's
procedure kind declares (`bench.report.figures.FigureSpec`, `bench.kind.RecordsPart`;
`bench.kind.declared_figures(kinds)` lists them with words, units and result.json
paths). The records store the rows the kind reads from result.json, with its checks'
tolerance and verdict; no kind is guessed from the keys of a result.
Times are UTC-aware datetimes. All dataclasses are frozen.
"""

from __future__ import annotations

import importlib
from typing import Any

#: public name -> submodule; loaded on first use so `bench --help` stays quick
_EXPORTS = {
    "FigureRecord": "extract", "NotARun": "extract", "RunRecord": "extract",
    "find_runs": "extract", "record_of": "extract",
    "RecordsTarget": "hooks", "target": "hooks",
    "LabSettings": "settings", "SettingsError": "settings", "load_lab_settings": "settings",
    "DueItem": "store", "Records": "store", "RecordsError": "store", "RunInfo": "store",
    "TableInfo": "store", "TrendPoint": "store",
    "trend_png": "trend",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(f"bench.app.records.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module 'bench.app.records' has no attribute {name!r}")
