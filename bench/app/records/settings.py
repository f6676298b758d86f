"""Lab settings: where the records live and how often each table is recertified.

Read once into a frozen `LabSettings`. The file is `lab.yaml` in the runs folder, or the
file named by the environment variable BENCH_LAB_SETTINGS, the lab file the DCC reads its
laboratory and signing key from (a lab server's URL shared by every bench is written there
once instead of on every command line); only these two keys are read here:

    records: postgresql://bench@labserver/records     # else records.sqlite in the runs folder
    recertification:
      default_interval_days: 365                      # tables that say nothing else
      tables: {SIM-0001: 180}                         # per serial; wins over the stand file
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.core.yamlfile import YamlError, load_yaml

LAB_FILE = "lab.yaml"
LAB_ENV = "BENCH_LAB_SETTINGS"          # the same lab file as the DCC's (bench/app/dcc/settings.py)
RECORDS_FILE = "records.sqlite"
DEFAULT_RUNS = "runs"


class SettingsError(ValueError):
    """A lab settings file that cannot be used; the message names file and key."""


@dataclass(frozen=True)
class LabSettings:
    path: Path | None = None
    records_url: str | None = None
    default_interval_days: int | None = None
    interval_days: dict[str, int] = field(default_factory=dict)

    def interval_for(self, serial: str, stand_days: int | None) -> int | None:
        """Per-serial lab setting, else the stand file's, else the lab's default."""
        return self.interval_days.get(serial) or stand_days or self.default_interval_days


def _days(value: Any, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | float) or value <= 0:
        raise SettingsError(f"{where}: expected a positive number of days, got {value!r}")
    return int(value)


def load_lab_settings(runs_dir: str | Path | None = None,
                      path: str | Path | None = None) -> LabSettings:
    """The lab settings in force: `path`, else $BENCH_LAB_SETTINGS, else RUNS_DIR/lab.yaml, else none."""
    chosen = path or os.environ.get(LAB_ENV) or None
    if chosen is None:
        candidate = Path(runs_dir or DEFAULT_RUNS) / LAB_FILE
        if not candidate.is_file():
            return LabSettings()
        chosen = candidate
    p = Path(chosen)
    try:   # the project's YAML reader, as for every reader of the lab file (bench.core.lab)
        data = load_yaml(p).data or {}
    except YamlError as e:
        raise SettingsError(f"{p}: cannot read the lab settings: {e.problem}") from None
    if not isinstance(data, dict):
        raise SettingsError(f"{p}: expected a mapping (records:, recertification:)")
    url = data.get("records")
    if url is not None and not isinstance(url, str):
        raise SettingsError(f"{p}: records: expected a database URL, got {url!r}")
    rec = data.get("recertification") or {}
    if not isinstance(rec, dict):
        raise SettingsError(f"{p}: recertification: expected a mapping")
    default = rec.get("default_interval_days")
    tables = rec.get("tables") or {}
    if not isinstance(tables, dict):
        raise SettingsError(f"{p}: recertification.tables: expected serial: days")
    return LabSettings(
        path=p, records_url=url,
        default_interval_days=_days(default, f"{p}: recertification.default_interval_days")
        if default is not None else None,
        interval_days={str(k): _days(v, f"{p}: recertification.tables.{k}")
                       for k, v in tables.items()})


def records_url(runs_dir: str | Path | None = None, url: str | None = None,
                settings: LabSettings | None = None) -> str:
    """--records URL, else the lab settings' records:, else RUNS_DIR/records.sqlite."""
    if url:
        return url
    if settings is not None and settings.records_url:
        return settings.records_url
    path = (Path(runs_dir or DEFAULT_RUNS) / RECORDS_FILE).resolve()
    return f"sqlite:///{path}"
