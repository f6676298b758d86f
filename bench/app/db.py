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
    args: dict[str, float] = {}
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


def reason_in_words(e: BaseException) -> str:
    """Why a database could not be read, in words: the driver's own reason without its
    class name or SQLAlchemy's wrapping (a psycopg `OperationalError: connection failed:
    ... Connection refused` is "the server refuses connections (not running, or not
    listening there)")."""
    text = str(getattr(e, "orig", None) or e).strip()
    low = text.lower()
    known = (("connection refused", "the server refuses connections (not running, or not "
                                    "listening there)"),
             ("timeout expired", "no answer from the server (cut from the network?)"),
             ("timed out", "no answer from the server (cut from the network?)"),
             ("password authentication failed", "the server refuses the login (password "
                                                "authentication failed)"),
             ("no password supplied", "no password for the login (~/.pgpass)"),
             ("is not currently accepting connections", "the server accepts no connections "
                                                         "to this database now"),
             ("the database system is shutting down", "the server is shutting down"),
             ("the database system is starting up", "the server is starting up"),
             ("terminating connection", "the server ended the connection (restarted?)"),
             ("server closed the connection", "the server closed the connection "
                                              "(restarted?)"),
             ("could not translate host name", "the server's host name is unknown"),
             ("no such host", "the server's host name is unknown"))
    for marker, words in known:
        if marker in low:
            return words
    first = text.splitlines()[0] if text else type(e).__name__
    return first.split(": ", 1)[1] if first.startswith(("psycopg", "sqlalchemy")) and \
        ": " in first else first


def away_text(url: str, e: BaseException, what: str = "lab database") -> str:
    """The words a page or a console shows while a database is away."""
    return f"the {what} {redact(url)} is away: {reason_in_words(e)}"
