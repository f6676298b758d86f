"""The first register schema: accounts, equipment, deviations, numbers, revisions, audit.

Revision ID: g0001
Revises:
Create Date: 2026-11-27
"""

from __future__ import annotations

from alembic import op

from bench.app.register import pgsql
from bench.app.register.schema import metadata

revision = "g0001"
down_revision = None
branch_labels = None
depends_on = None

#: SQLite: the register's own code never deletes or rewrites these; a trigger makes a
#: mistake by hand fail loudly (a file's owner can drop triggers: docs/register.md)
SQLITE_GUARDS = [
    """CREATE TRIGGER reg_audit_no_update BEFORE UPDATE ON reg_audit
       BEGIN SELECT RAISE(ABORT, 'the audit trail is append-only'); END""",
    """CREATE TRIGGER reg_audit_no_delete BEFORE DELETE ON reg_audit
       BEGIN SELECT RAISE(ABORT, 'the audit trail is append-only'); END""",
    """CREATE TRIGGER reg_revisions_no_delete BEFORE DELETE ON reg_revisions
       BEGIN SELECT RAISE(ABORT, 'an issued revision is never removed'); END""",
    """CREATE TRIGGER reg_revisions_only_withdrawn BEFORE UPDATE ON reg_revisions
       WHEN OLD.withdrawn_utc IS NOT NULL OR NEW.number IS NOT OLD.number
            OR NEW.revision IS NOT OLD.revision OR NEW.pdf_sha256 IS NOT OLD.pdf_sha256
            OR NEW.dcc_sha256 IS NOT OLD.dcc_sha256 OR NEW.signatory IS NOT OLD.signatory
            OR NEW.result_sha256 IS NOT OLD.result_sha256
       BEGIN SELECT RAISE(ABORT, 'an issued revision is only ever marked withdrawn'); END""",
    """CREATE TRIGGER reg_certificates_no_delete BEFORE DELETE ON reg_certificates
       BEGIN SELECT RAISE(ABORT, 'an allocated number is never removed'); END""",
]


def upgrade() -> None:
    bind = op.get_bind()
    # the first revision's tables are schema.py's as of this revision; later changes to
    # schema.py come with their own migration written with op.* (as the records' do)
    metadata.create_all(bind)
    if bind.dialect.name == "postgresql":
        for sql in (*pgsql.FUNCTIONS, *pgsql.REVOKE_PUBLIC):
            op.execute(sql)
    elif bind.dialect.name == "sqlite":
        for sql in SQLITE_GUARDS:
            op.execute(sql)


def downgrade() -> None:
    raise NotImplementedError("the register is never downgraded: its records are kept")
