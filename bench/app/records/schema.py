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
