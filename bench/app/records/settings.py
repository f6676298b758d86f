"""Lab settings: where the records live and how often each table is recertified.

Read once into a frozen `LabSettings`. The file is the one the command chose
(bench/app/labfile.py: `--lab FILE`, else the environment variable BENCH_LAB_SETTINGS, or
for a run's own commands the run's copy), the lab file the DCC reads its
laboratory and signing key from (a lab server's URL shared by every bench is written there
once instead of on every command line); the records use these two keys of it:

    records: postgresql://bench@labserver/records     # else records.sqlite in the runs folder
    recertification:
      default_interval_days: 365                      # tables that say nothing else
      tables: {SIM-0001: 180}                         # per serial; wins over the stand file
"""

from __future__ import annotations

import os
from pathlib import Path

from bench.app.names import DEFAULT_RUNS
from bench.core.lab import Lab, LabError, load_lab

LAB_FILE = "lab.yaml"
LAB_ENV = "BENCH_LAB_SETTINGS"          # the same lab file as the DCC's (bench/app/dcc/settings.py)
RECORDS_FILE = "records.sqlite"


#: the one lab settings model and its error (bench/core/lab.py): the records read the same
#: file, validated by the same schema, as the certificate and the DCC
LabSettings = Lab
SettingsError = LabError


def load_lab_settings(runs_dir: str | Path | None = None,
                      path: str | Path | None = None) -> Lab:
    """The lab settings in force: `path` (the command's choice, bench/app/labfile.py),
    else $BENCH_LAB_SETTINGS, else none (every default then, bench/core/lab.py). A lab.yaml
    in the runs folder is not read (`stray_lab_file`)."""
    chosen = path or os.environ.get(LAB_ENV) or None
    return load_lab(chosen) if chosen is not None else Lab()


def stray_lab_file(runs_dir: str | Path | None) -> str | None:
    """What to say of a lab.yaml in a runs folder when a command chose no lab file: it is
    no longer read (docs/station.md, "The lab file: one rule"), and a command that would
    have read it refuses, saying so, rather than write the lab's records elsewhere."""
    candidate = Path(runs_dir or DEFAULT_RUNS) / LAB_FILE
    if not candidate.is_file():
        return None
    return (f"{candidate}: a lab file in the runs folder is not read (one rule for the lab "
            f"file, docs/station.md): name it with --lab {candidate} or "
            f"{LAB_ENV}={candidate.resolve()}, or move it")


def records_url(runs_dir: str | Path | None = None, url: str | None = None,
                settings: LabSettings | None = None) -> str:
    """--records URL, else the lab settings' records:, else RUNS_DIR/records.sqlite."""
    if url:
        return url
    if settings is not None and settings.records_url:
        return settings.records_url
    path = (Path(runs_dir or DEFAULT_RUNS) / RECORDS_FILE).resolve()
    return f"sqlite:///{path}"
