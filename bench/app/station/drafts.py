"""Every bench's drafts, from the lab database, and where the station finds each one's run
directory (issue 59).

A draft is a run the records hold that ended with a verdict and no certificate number yet
(as `Records.drafts` says it), listed here with the bench that delivered it (its
`bench_runs` row, when a bench delivered it) so that its page and its Sign form can be
reached. Its files are read from the station's runs folders (its own, then the other
benches' folders it was given, `--other-runs`): a folder holding a directory of the run's
name whose meta.json carries the run's uid. Nothing else is trusted to name a folder, so
two benches' runs of one name are never confused.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import sqlalchemy as sa
from sqlalchemy.engine import Engine

from bench.app.records import schema as s
from bench.app.records.extract import run_uid
from bench.core import rundir_layout as layout
from bench.core.journal_codec import read_meta


@dataclass(frozen=True)
class Draft:
    """One draft as the lab database holds it."""

    uid: str
    bench: str | None           # the bench that delivered it (None: registered otherwise)
    run_dir: str                # the run directory's name
    run_path: str | None        # where it was at its bench (as the bench registered it)
    serial: str
    verdict: str
    date_utc: dt.datetime | None
    operator: str | None
    simulated: bool


def drafts(engine: Engine, limit: int = 50, simulated: bool = False) -> list[Draft]:
    """The records' runs that ended with a verdict (pass or fail), not aborted, with no
    certificate number, newest first, each with the bench that delivered it."""
    r, t, br, b = s.runs.c, s.tables.c, s.bench_runs.c, s.benches.c
    date = sa.func.coalesce(r.completed_utc, r.started_utc, r.created_utc)
    delivered = (sa.select(br.uid, sa.func.min(b.name).label("bench"))
                 .join(s.benches, b.id == br.bench_id).group_by(br.uid).subquery())
    with engine.connect() as conn:
        rows = conn.execute(
            sa.select(r.uid, r.run_dir, r.run_path, r.verdict, r.operator, r.simulated,
                      t.serial, date.label("date"), delivered.c.bench)
            .join(s.tables, r.table_id == t.id)
            .outerjoin(delivered, delivered.c.uid == r.uid)
            .where(r.certificate_number.is_(None), r.verdict.in_(("pass", "fail")),
                   r.aborted.is_(False), r.simulated.is_(simulated))
            .order_by(date.desc(), r.id.desc()).limit(limit)).all()
    return [Draft(x.uid, x.bench, x.run_dir, x.run_path, x.serial, x.verdict, x.date,
                  x.operator, bool(x.simulated)) for x in rows]


def find_run(folders: Sequence[Path], run_dir: str, uid: str) -> Path | None:
    """The run directory `run_dir` whose meta.json names run `uid`, directly inside one of
    the runs folders (the first that has it), or None."""
    if not run_dir or "/" in run_dir or "\\" in run_dir or run_dir.startswith("."):
        return None
    for folder in folders:
        root = folder.resolve()
        p = (root / run_dir).resolve()
        if p.parent != root or not (p / layout.EVENTS).is_file():
            continue
        try:
            meta = read_meta(p / layout.META)
        except (OSError, ValueError):
            continue
        if run_uid(meta, p.name) == uid:
            return p
    return None
