"""The lab's databases (the records, the register, the lab page's live tables): how a
URL becomes an SQLAlchemy engine, and how a migration set is brought to its head. One
place, so the records and the register connect, wait for a locked SQLite file and time
out on an unreachable server alike.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import TYPE_CHECKING

import sqlalchemy as sa
from sqlalchemy import event
from sqlalchemy.engine import Connection, Engine

if TYPE_CHECKING:
    import sqlite3

    from sqlalchemy.pool import ConnectionPoolEntry

CONNECT_TIMEOUT_S = 5          # an unreachable lab server must not hold a run up
SQLITE_BUSY_S = 30.0           # another bench holding the SQLite file: wait this long
#: Alembic's command API keeps its context in module globals: one migration at a time
#: per process (other processes are kept apart by the database's own transactions)
_MIGRATE_LOCK = threading.Lock()


def engine_url(url: str) -> str:
    """postgresql:// means psycopg (version 3), the driver this project installs."""
    for prefix in ("postgresql://", "postgres://"):
        if url.startswith(prefix):
            return "postgresql+psycopg://" + url[len(prefix):]
    return url


def make_engine(url: str) -> Engine:
    real = engine_url(url)
    if real.startswith("sqlite"):
        path = real.split("///", 1)[1] if "///" in real else ""
        if path and path != ":memory:":
            Path(path).parent.mkdir(parents=True, exist_ok=True)
        eng = sa.create_engine(real, connect_args={"timeout": SQLITE_BUSY_S})

        # pysqlite opens transactions lazily and cannot wait for a write lock once it
        # holds a read lock; BEGIN IMMEDIATE takes the write lock up front, so a second
        # writer waits (busy timeout) instead of failing (SQLAlchemy's documented recipe).
        @event.listens_for(eng, "connect")
        def _no_implicit_begin(dbapi_conn: sqlite3.Connection, _rec: ConnectionPoolEntry
                               ) -> None:
            dbapi_conn.isolation_level = None
            dbapi_conn.execute("PRAGMA foreign_keys=ON")

        @event.listens_for(eng, "begin")
        def _begin_immediate(conn: Connection) -> None:
            conn.exec_driver_sql("BEGIN IMMEDIATE")

        return eng
    args: dict[str, object] = {}
    if real.startswith("postgresql"):
        args["connect_timeout"] = CONNECT_TIMEOUT_S
    return sa.create_engine(real, connect_args=args, pool_pre_ping=True)


def upgrade_to_head(engine: Engine, script_location: Path) -> None:
    """Bring the database to the newest migration of the set at `script_location`
    (Alembic, in-process, in one transaction)."""
    from alembic import command
    from alembic.config import Config as AlembicConfig

    cfg = AlembicConfig()
    cfg.set_main_option("script_location", str(script_location))
    with _MIGRATE_LOCK, engine.begin() as conn:
        cfg.attributes["connection"] = conn
        command.upgrade(cfg, "head")


def redact(url: str) -> str:
    """A URL without its password, for messages."""
    try:
        return sa.engine.make_url(url).render_as_string(hide_password=True)
    except Exception:  # noqa: BLE001
        return url
