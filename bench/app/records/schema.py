"""The records database's tables (SQLAlchemy Core), the same on SQLite and PostgreSQL.

One row per table calibrated (`tables`, keyed by serial), per run (`runs`, keyed by a uid
derived from the run directory so a re-import finds it again), per reported figure with
its U and verdict (`figures`), and per certificate file with its SHA-256 (`cert_files`).
Times are stored as naive UTC (SQLite has no time zones); the read API adds UTC back.
The migrations in `migrations/versions` create exactly this; change both together.
"""

from __future__ import annotations

import sqlalchemy as sa

metadata = sa.MetaData()

tables = sa.Table(
    "tables", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("serial", sa.String(120), nullable=False, unique=True),
    sa.Column("maker", sa.String(200)),
    sa.Column("model", sa.String(200)),
    sa.Column("location", sa.String(200)),
    sa.Column("interval_days", sa.Integer),          # recertification interval (stand file)
    sa.Column("first_seen_utc", sa.DateTime),
    sa.Column("last_seen_utc", sa.DateTime),
)

runs = sa.Table(
    "runs", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("uid", sa.String(64), nullable=False, unique=True),
    sa.Column("table_id", sa.Integer, sa.ForeignKey("tables.id"), nullable=False, index=True),
    sa.Column("kind", sa.String(40), nullable=False),
    sa.Column("title", sa.Text),
    sa.Column("run_dir", sa.String(255), nullable=False),
    sa.Column("run_path", sa.Text),
    sa.Column("host", sa.String(255)),
    sa.Column("procedure_name", sa.String(255)),
    sa.Column("procedure_sha256", sa.String(64)),
    sa.Column("stand_sha256", sa.String(64)),
    sa.Column("result_sha256", sa.String(64)),
    sa.Column("created_utc", sa.DateTime),
    sa.Column("started_utc", sa.DateTime),
    sa.Column("completed_utc", sa.DateTime),
    sa.Column("registered_utc", sa.DateTime, nullable=False),
    sa.Column("operator", sa.String(200)),
    sa.Column("verdict", sa.String(20), nullable=False),
    sa.Column("calibration_state", sa.String(20)),   # as-found | as-left | None
    sa.Column("adjustment_note", sa.Text),
    sa.Column("certificate_number", sa.String(120)),
    sa.Column("simulated", sa.Boolean, nullable=False, default=False),
    sa.Column("sessions", sa.Integer),
    sa.Column("aborted", sa.Boolean, nullable=False, default=False),
    sa.Column("bench_version", sa.String(40)),
    # r0004: the role that registered the run (PostgreSQL: its default, current_user); the
    # only role that may change it (row-level security)
    sa.Column("db_role", sa.Text),
)

figures = sa.Table(
    "figures", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("run_id", sa.Integer, sa.ForeignKey("runs.id", ondelete="CASCADE"),
              nullable=False, index=True),
    sa.Column("axis", sa.String(60), nullable=False),
    sa.Column("quantity", sa.String(80), nullable=False),
    sa.Column("set_rate_dps", sa.Float),              # signed; a pair's magnitude; None
    sa.Column("value", sa.Float, nullable=False),
    sa.Column("u", sa.Float),                         # expanded, k = 2, same unit
    sa.Column("unit", sa.String(20), nullable=False),
    sa.Column("tolerance", sa.Float),
    sa.Column("verdict", sa.String(20)),
    sa.Column("rule", sa.String(40)),
)

cert_files = sa.Table(
    "cert_files", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("run_id", sa.Integer, sa.ForeignKey("runs.id", ondelete="CASCADE"),
              nullable=False, index=True),
    sa.Column("name", sa.String(255), nullable=False),
    sa.Column("sha256", sa.String(64), nullable=False),
    sa.Column("bytes", sa.BigInteger, nullable=False),
    sa.UniqueConstraint("run_id", "name", name="uq_cert_files_run_name"),
)

# -- measurement assurance (ISO/IEC 17025 7.7; migration r0002) ------------------------------

instruments = sa.Table(
    "instruments", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("serial", sa.String(120), nullable=False, unique=True),
    sa.Column("role", sa.String(40), nullable=False),     # fog | counter | drive | gyro
    sa.Column("model", sa.String(200)),
    sa.Column("first_seen_utc", sa.DateTime),
    sa.Column("last_seen_utc", sa.DateTime),
)

checks = sa.Table(
    "checks", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("run_id", sa.Integer, sa.ForeignKey("runs.id", ondelete="CASCADE"),
              nullable=False, index=True),
    sa.Column("instrument_id", sa.Integer, sa.ForeignKey("instruments.id"), nullable=False,
              index=True),
    sa.Column("axis", sa.String(60), nullable=False),
    sa.Column("quantity", sa.String(80), nullable=False),
    sa.Column("set_rate_dps", sa.Float),              # |rate| of a per-rate value, else None
    sa.Column("value", sa.Float, nullable=False),
    sa.Column("u", sa.Float),                         # expanded, k = 2, same unit
    sa.Column("unit", sa.String(20), nullable=False),
)

reviews = sa.Table(                                   # append-only: the review journal
    "reviews", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("instrument_id", sa.Integer, sa.ForeignKey("instruments.id"), nullable=False,
              index=True),
    sa.Column("utc", sa.DateTime, nullable=False),
    sa.Column("reviewer", sa.String(200), nullable=False),
    sa.Column("text", sa.Text, nullable=False),
    sa.Column("status", sa.Text),                     # the status it reviewed, as shown
    sa.Column("through_utc", sa.DateTime),            # covers signals of runs up to this date
    sa.Column("new_baseline", sa.Boolean),            # the chart restarts at that run
    sa.Column("host", sa.String(255)),
)

# -- the lab's benches and their live runs (issue 44; migration r0003) -----------------------
# What each bench delivers from its run directories (bench/app/fleet/sync.py): the runs it
# has, every line of their event logs under (run, sequence number) so a delivery repeated
# after an outage or a kill adds nothing, the health it sampled, and the final result.

benches = sa.Table(
    "benches", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("name", sa.String(120), nullable=False, unique=True),   # stand file bench.name
    sa.Column("host", sa.String(255)),
    sa.Column("first_seen_utc", sa.DateTime),         # the lab server's clock
    sa.Column("last_seen_utc", sa.DateTime),
    # r0004: the database role bound to this bench's name (PostgreSQL: row-level security)
    sa.Column("db_role", sa.Text),
)

bench_runs = sa.Table(
    "bench_runs", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("bench_id", sa.Integer, sa.ForeignKey("benches.id"), nullable=False),
    sa.Column("uid", sa.String(64), nullable=False),  # the records' run uid (extract.run_uid)
    sa.Column("run_dir", sa.String(255), nullable=False),
    sa.Column("title", sa.Text),
    sa.Column("kind", sa.String(40)),
    sa.Column("serial", sa.String(120)),
    sa.Column("maker", sa.String(200)),
    sa.Column("model", sa.String(200)),
    sa.Column("simulated", sa.Boolean),
    sa.Column("created_utc", sa.DateTime),
    sa.Column("last_seq", sa.Integer, nullable=False, default=0),   # event lines delivered
    sa.Column("last_event_utc", sa.DateTime),         # the bench's clock, its last event
    sa.Column("health", sa.JSON),                     # sampled at the bench (fleet/health.py)
    sa.Column("health_utc", sa.DateTime),             # the bench's clock, when sampled
    sa.Column("received_utc", sa.DateTime),           # the lab server's clock, last delivery
    sa.Column("result", sa.JSON),                     # result.json once written
    sa.Column("result_sha256", sa.String(64)),
    sa.Column("verdict", sa.String(20)),              # its verdict (the list reads this only)
    sa.UniqueConstraint("bench_id", "uid", name="uq_bench_runs_bench_uid"),
)
sa.Index("ix_bench_runs_received", bench_runs.c.received_utc)

bench_events = sa.Table(
    "bench_events", metadata,
    sa.Column("run_id", sa.Integer, sa.ForeignKey("bench_runs.id", ondelete="CASCADE"),
              primary_key=True),
    sa.Column("seq", sa.Integer, primary_key=True),   # its line number in events.jsonl
    sa.Column("utc", sa.DateTime),
    sa.Column("event", sa.String(60)),
    sa.Column("body", sa.JSON, nullable=False),       # the event as journaled
)
