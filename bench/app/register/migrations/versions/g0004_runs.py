"""Issue 54, what is issued is what was measured: the register holds each run from its
start (reg_runs) with its sessions and analyses (reg_run_events).

Revision ID: g0004
Revises: g0003
Create Date: 2026-11-29
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from bench.app.register import pgsql

revision = "g0004"
down_revision = "g0003"
branch_labels = None
depends_on = None


def upgrade() -> None:
    bind = op.get_bind()
    have = set(sa.inspect(bind).get_table_names())
    if "reg_runs" not in have:
        op.create_table(
            "reg_runs",
            sa.Column("uid", sa.String(64), primary_key=True),
            sa.Column("bench", sa.String(200), nullable=False),
            sa.Column("performer", sa.String(120)),
            sa.Column("version", sa.String(60), nullable=False),
            sa.Column("simulated", sa.Boolean, nullable=False),
            sa.Column("inputs", sa.Text, nullable=False),
            sa.Column("items", sa.Text, nullable=False),
            sa.Column("registered_utc", sa.String(40), nullable=False),
            sa.Column("via", sa.String(200), nullable=False),
            sa.Column("result_sha256", sa.String(64)),
            sa.Column("result", sa.Text),
            sa.Column("result_utc", sa.String(40)),
            sa.Column("raw", sa.Text, nullable=False))
    if "reg_run_events" not in have:
        op.create_table(
            "reg_run_events",
            sa.Column("id", sa.Integer, primary_key=True),
            sa.Column("uid", sa.String(64), sa.ForeignKey("reg_runs.uid"), nullable=False),
            sa.Column("utc", sa.String(40), nullable=False),
            sa.Column("kind", sa.String(20), nullable=False),
            sa.Column("detail", sa.Text, nullable=False))
    if bind.dialect.name == "postgresql":
        # the roles that read the inventory read the runs; the service (which writes the
        # inventory) writes them; no other role writes a run's record
        op.execute(pgsql.grants_like_inventory(
            "GRANT SELECT ON reg_runs, reg_run_events TO %I",
            "GRANT INSERT, UPDATE ON reg_runs TO %I; GRANT INSERT ON reg_run_events TO %I; "
            "GRANT USAGE ON ALL SEQUENCES IN SCHEMA public TO %I"))


def downgrade() -> None:
    raise NotImplementedError("the register is never downgraded: its records are kept")
