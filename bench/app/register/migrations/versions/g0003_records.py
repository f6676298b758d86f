"""Issue 55, the register's records: every calibration of an item with its as-found
status, identity-only items, revocable deviations, withdrawal with reason and by whom.

Revision ID: g0003
Revises: g0002
Create Date: 2026-11-29
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from bench.app.register import pgsql

revision = "g0003"
down_revision = "g0002"
branch_labels = None
depends_on = None


def _add(table: str, *columns: sa.Column[object]) -> None:
    have = {c["name"] for c in sa.inspect(op.get_bind()).get_columns(table)}
    missing = [c for c in columns if c.name not in have]
    if missing:
        with op.batch_alter_table(table) as b:
            for c in missing:
                b.add_column(c)


def upgrade() -> None:
    bind = op.get_bind()
    insp = sa.inspect(bind)
    _add("reg_revisions", sa.Column("withdrawn_reason", sa.Text),
         sa.Column("withdrawn_by", sa.String(120)))
    _add("reg_deviations", sa.Column("revoked_utc", sa.String(40)),
         sa.Column("revoked_by", sa.String(120)))
    _add("reg_equipment", sa.Column("identity_only", sa.Boolean, nullable=False,
                                    server_default=sa.false()))
    cols = {c["name"]: c for c in insp.get_columns("reg_equipment")}
    if not cols["certificate"]["nullable"] and bind.dialect.name == "postgresql":
        for name in ("certificate", "issuer", "due_date"):    # an identity-only item has none
            op.execute(f"ALTER TABLE reg_equipment ALTER COLUMN {name} DROP NOT NULL")
    # an SQLite register made before this keeps its NOT NULL columns (recreating the table
    # would drop its rows' guards): an identity-only item there stores '' (store.py)
    if "reg_calibrations" not in insp.get_table_names():
        op.create_table(
            "reg_calibrations",
            sa.Column("id", sa.Integer, primary_key=True),
            sa.Column("serial", sa.String(120), sa.ForeignKey("reg_equipment.serial"),
                      nullable=False),
            sa.Column("certificate", sa.String(200), nullable=False),
            sa.Column("issuer", sa.String(200), nullable=False),
            sa.Column("calibrated_on", sa.String(10)),
            sa.Column("due_date", sa.String(10), nullable=False),
            sa.Column("found", sa.String(3)),
            sa.Column("found_error", sa.Float),
            sa.Column("found_error_u", sa.Float),
            sa.Column("recorded_utc", sa.String(40), nullable=False),
            sa.Column("recorded_by", sa.String(120), nullable=False))
        # each item's calibration so far becomes its first record
        op.execute("INSERT INTO reg_calibrations (serial, certificate, issuer, due_date, "
                   "recorded_utc, recorded_by) SELECT serial, certificate, issuer, due_date, "
                   "added_utc, added_by FROM reg_equipment WHERE certificate IS NOT NULL")
    if bind.dialect.name == "postgresql":
        # the roles that read the inventory read its history; the service writes it
        op.execute(pgsql.grants_like_inventory(
            "GRANT SELECT ON reg_calibrations TO %I",
            "GRANT INSERT ON reg_calibrations TO %I; GRANT UPDATE (withdrawn_utc, "
            "withdrawn_reason, withdrawn_by) ON reg_revisions TO %I; "
            "GRANT USAGE ON ALL SEQUENCES IN SCHEMA public TO %I"))


def downgrade() -> None:
    raise NotImplementedError("the register is never downgraded: its records are kept")
