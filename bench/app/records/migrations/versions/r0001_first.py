"""The first records schema: tables, runs, figures, certificate files.

Revision ID: r0001
Revises:
Create Date: 2026-11-22
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "r0001"
down_revision = None
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "tables",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("serial", sa.String(120), nullable=False, unique=True),
        sa.Column("maker", sa.String(200)),
        sa.Column("model", sa.String(200)),
        sa.Column("location", sa.String(200)),
        sa.Column("interval_days", sa.Integer),
        sa.Column("first_seen_utc", sa.DateTime),
        sa.Column("last_seen_utc", sa.DateTime),
    )
    op.create_table(
        "runs",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("uid", sa.String(64), nullable=False, unique=True),
        sa.Column("table_id", sa.Integer, sa.ForeignKey("tables.id"), nullable=False,
                  index=True),
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
        sa.Column("calibration_state", sa.String(20)),
        sa.Column("adjustment_note", sa.Text),
        sa.Column("certificate_number", sa.String(120)),
        sa.Column("simulated", sa.Boolean, nullable=False),
        sa.Column("sessions", sa.Integer),
        sa.Column("aborted", sa.Boolean, nullable=False),
        sa.Column("bench_version", sa.String(40)),
    )
    op.create_table(
        "figures",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("run_id", sa.Integer, sa.ForeignKey("runs.id", ondelete="CASCADE"),
                  nullable=False, index=True),
        sa.Column("axis", sa.String(60), nullable=False),
        sa.Column("quantity", sa.String(80), nullable=False),
        sa.Column("set_rate_dps", sa.Float),
        sa.Column("value", sa.Float, nullable=False),
        sa.Column("u", sa.Float),
        sa.Column("unit", sa.String(20), nullable=False),
        sa.Column("tolerance", sa.Float),
        sa.Column("verdict", sa.String(20)),
        sa.Column("rule", sa.String(40)),
    )
    op.create_table(
        "cert_files",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("run_id", sa.Integer, sa.ForeignKey("runs.id", ondelete="CASCADE"),
                  nullable=False, index=True),
        sa.Column("name", sa.String(255), nullable=False),
        sa.Column("sha256", sa.String(64), nullable=False),
        sa.Column("bytes", sa.BigInteger, nullable=False),
        sa.UniqueConstraint("run_id", "name", name="uq_cert_files_run_name"),
    )


def downgrade() -> None:
    for name in ("cert_files", "figures", "runs", "tables"):
        op.drop_table(name)
