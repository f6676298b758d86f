"""Each bench writes only its own rows (issue 53, item 4): PostgreSQL row-level security.

Revision ID: r0004
Revises: r0003
Create Date: 2026-11-29

A bench's database role is bound to its name (`bench records bench add NAME --role ROLE`,
the owner acts): `benches.db_role`. The rows a role writes carry it (`runs.db_role`,
defaulting to the role that inserts), and the policies below let a role insert, change or
delete a fleet row, a registered run and that run's figures, files and check values only
where the row is its own. Reading stays open (the station, the control charts). The
table's owner (the lab's migrations and `bench records import` as the owner) is not
subject to the policies. SQLite, one bench, has nothing to keep apart: unchanged.
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "r0004"
down_revision = "r0003"
branch_labels = None
depends_on = None

MINE_RUN = "run_id IN (SELECT id FROM runs WHERE db_role = current_user)"
MINE_BENCH = "bench_id IN (SELECT id FROM benches WHERE db_role = current_user)"
MINE_BENCH_RUN = ("run_id IN (SELECT r.id FROM bench_runs r JOIN benches b ON b.id = "
                  "r.bench_id WHERE b.db_role = current_user)")
#: table -> the condition a non-owner role's writes must meet
OWN_ROWS = {
    "benches": "db_role = current_user",
    "bench_runs": MINE_BENCH,
    "bench_events": MINE_BENCH_RUN,
    "runs": "db_role = current_user",
    "figures": MINE_RUN,
    "cert_files": MINE_RUN,
    "checks": MINE_RUN,
}


def upgrade() -> None:
    if op.get_bind().dialect.name != "postgresql":
        for table in ("benches", "runs"):       # the column, without the role behind it
            with op.batch_alter_table(table) as b:
                b.add_column(sa.Column("db_role", sa.Text))
        return
    op.execute("ALTER TABLE benches ADD COLUMN IF NOT EXISTS db_role text "
               "DEFAULT current_user")
    op.execute("ALTER TABLE runs ADD COLUMN IF NOT EXISTS db_role text DEFAULT current_user")
    for table, mine in OWN_ROWS.items():
        op.execute(f"ALTER TABLE {table} ENABLE ROW LEVEL SECURITY")
        op.execute(f"CREATE POLICY {table}_read ON {table} FOR SELECT USING (true)")
        op.execute(f"CREATE POLICY {table}_insert ON {table} FOR INSERT WITH CHECK ({mine})")
        op.execute(f"CREATE POLICY {table}_update ON {table} FOR UPDATE USING ({mine}) "
                   f"WITH CHECK ({mine})")
        op.execute(f"CREATE POLICY {table}_delete ON {table} FOR DELETE USING ({mine})")


def downgrade() -> None:
    raise NotImplementedError("the records are never downgraded")
