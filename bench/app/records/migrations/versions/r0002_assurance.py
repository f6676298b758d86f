"""Measurement assurance: instruments, their check values per run, the review journal.

Revision ID: r0002
Revises: r0001
Create Date: 2026-11-24
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "r0002"
down_revision = "r0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "instruments",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("serial", sa.String(120), nullable=False, unique=True),
        sa.Column("role", sa.String(40), nullable=False),
        sa.Column("model", sa.String(200)),
        sa.Column("first_seen_utc", sa.DateTime),
        sa.Column("last_seen_utc", sa.DateTime),
    )
    op.create_table(
        "checks",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("run_id", sa.Integer, sa.ForeignKey("runs.id", ondelete="CASCADE"),
                  nullable=False, index=True),
        sa.Column("instrument_id", sa.Integer, sa.ForeignKey("instruments.id"),
                  nullable=False, index=True),
        sa.Column("axis", sa.String(60), nullable=False),
        sa.Column("quantity", sa.String(80), nullable=False),
        sa.Column("set_rate_dps", sa.Float),
        sa.Column("value", sa.Float, nullable=False),
        sa.Column("u", sa.Float),
        sa.Column("unit", sa.String(20), nullable=False),
    )
    op.create_table(
        "reviews",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("instrument_id", sa.Integer, sa.ForeignKey("instruments.id"),
                  nullable=False, index=True),
        sa.Column("utc", sa.DateTime, nullable=False),
        sa.Column("reviewer", sa.String(200), nullable=False),
        sa.Column("text", sa.Text, nullable=False),
        sa.Column("status", sa.Text),
        sa.Column("through_utc", sa.DateTime),
        sa.Column("new_baseline", sa.Boolean),
        sa.Column("host", sa.String(255)),
    )


def downgrade() -> None:
    for name in ("reviews", "checks", "instruments"):
        op.drop_table(name)
