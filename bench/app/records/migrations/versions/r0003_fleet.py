"""The lab's benches, their runs as delivered and every event line (issue 44).

Revision ID: r0003
Revises: r0002
Create Date: 2026-11-27

In the records' own migration set, not one of its own: the station reads a bench's live
run beside the table's history and due date through one URL, a delivered run is
registered in the same database, and one `Records.open` brings both to the newest schema.
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "r0003"
down_revision = "r0002"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "benches",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("name", sa.String(120), nullable=False, unique=True),
        sa.Column("host", sa.String(255)),
        sa.Column("first_seen_utc", sa.DateTime),
        sa.Column("last_seen_utc", sa.DateTime),
    )
    op.create_table(
        "bench_runs",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("bench_id", sa.Integer, sa.ForeignKey("benches.id"), nullable=False),
        sa.Column("uid", sa.String(64), nullable=False),
        sa.Column("run_dir", sa.String(255), nullable=False),
        sa.Column("title", sa.Text),
        sa.Column("kind", sa.String(40)),
        sa.Column("serial", sa.String(120)),
        sa.Column("maker", sa.String(200)),
        sa.Column("model", sa.String(200)),
        sa.Column("simulated", sa.Boolean),
        sa.Column("created_utc", sa.DateTime),
        sa.Column("last_seq", sa.Integer, nullable=False),
        sa.Column("last_event_utc", sa.DateTime),
        sa.Column("health", sa.JSON),
        sa.Column("health_utc", sa.DateTime),
        sa.Column("received_utc", sa.DateTime),
        sa.Column("result", sa.JSON),
        sa.Column("result_sha256", sa.String(64)),
        sa.Column("verdict", sa.String(20)),
        sa.UniqueConstraint("bench_id", "uid", name="uq_bench_runs_bench_uid"),
    )
    op.create_index("ix_bench_runs_received", "bench_runs", ["received_utc"])
    op.create_table(
        "bench_events",
        sa.Column("run_id", sa.Integer, sa.ForeignKey("bench_runs.id", ondelete="CASCADE"),
                  primary_key=True),
        sa.Column("seq", sa.Integer, primary_key=True),
        sa.Column("utc", sa.DateTime),
        sa.Column("event", sa.String(60)),
        sa.Column("body", sa.JSON, nullable=False),
    )


def downgrade() -> None:
    op.drop_table("bench_events")
    op.drop_index("ix_bench_runs_received", "bench_runs")
    op.drop_table("bench_runs")
    op.drop_table("benches")
