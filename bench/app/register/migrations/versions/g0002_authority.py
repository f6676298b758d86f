"""Issue 53, people hold the authority: password age and must-change on accounts, failed
logins and locks per name, and the grants of earlier registers narrowed (the benches'
role no longer runs the issuing functions or reads password hashes).

Revision ID: g0002
Revises: g0001
Create Date: 2026-11-29
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from bench.app.register import pgsql

revision = "g0002"
down_revision = "g0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    bind = op.get_bind()
    insp = sa.inspect(bind)
    # g0001 creates schema.py's tables as they are now; an older register lacks these
    have = {c["name"] for c in insp.get_columns("reg_accounts")}
    with op.batch_alter_table("reg_accounts") as b:
        if "must_change" not in have:
            b.add_column(sa.Column("must_change", sa.Boolean, nullable=False,
                                   server_default=sa.false()))
        if "password_changed_utc" not in have:
            b.add_column(sa.Column("password_changed_utc", sa.String(40)))
    if "reg_logins" not in insp.get_table_names():
        op.create_table(
            "reg_logins",
            sa.Column("name", sa.String(120), primary_key=True),
            sa.Column("failures", sa.Integer, nullable=False),
            sa.Column("first_failure_utc", sa.String(40)),
            sa.Column("locked_until_utc", sa.String(40)))
    if bind.dialect.name == "postgresql":
        op.execute(pgsql.REVOKE_EARLIER)


def downgrade() -> None:
    raise NotImplementedError("the register is never downgraded: its records are kept")
