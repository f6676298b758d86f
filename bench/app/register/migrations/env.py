"""Alembic environment: always run in-process on the connection the register opened."""

from __future__ import annotations

from alembic import context

from bench.app.register.schema import metadata

connection = context.config.attributes["connection"]
context.configure(connection=connection, target_metadata=metadata, render_as_batch=True,
                  version_table="register_alembic_version")
with context.begin_transaction():
    context.run_migrations()
