"""The lab database's PostgreSQL roles: what a bench and the station may do (docs/station.md).

The lab's owner role creates and migrates the schema (`bench records init URL`) and
grants the benches' role what a delivery and a registration need: read everything,
insert and update the runs, figures, check values and certificate digests it registers
(a re-analysed run replaces its own rows), insert and update benches and their runs, and
only insert event lines (a line once delivered is never changed, not even by its bench);
no DDL. The station's role reads. Row-level security (migration r0004) keeps each bench's
role to its own rows: the bench's name is bound to its role (`bind_bench`), and a role
writes only the fleet rows of its bench and the runs (with their figures, files and check
values) it registered.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from sqlalchemy.engine import Connection

RECORDS_TABLES = ("tables", "runs", "figures", "cert_files", "instruments", "checks")
FLEET_TABLES = ("benches", "bench_runs")
ALL_TABLES = (*RECORDS_TABLES, "reviews", *FLEET_TABLES, "bench_events",
              "records_alembic_version")


def _q(role: str) -> str:
    return '"' + role.replace('"', '""') + '"'


def bench_grants(role: str) -> list[str]:
    """A bench's role: register runs, deliver events, journal reviews; nothing else."""
    q = _q(role)
    return [
        f"GRANT USAGE ON SCHEMA public TO {q}",
        f"GRANT SELECT ON {', '.join(ALL_TABLES)} TO {q}",
        f"GRANT INSERT, UPDATE, DELETE ON {', '.join(RECORDS_TABLES)} TO {q}",
        f"GRANT INSERT ON reviews, bench_events TO {q}",
        f"GRANT INSERT, UPDATE ON {', '.join(FLEET_TABLES)} TO {q}",
        f"GRANT USAGE ON ALL SEQUENCES IN SCHEMA public TO {q}",
    ]


def station_grants(role: str) -> list[str]:
    """The station's role: read (LISTEN needs no grant)."""
    q = _q(role)
    return [f"GRANT USAGE ON SCHEMA public TO {q}",
            f"GRANT SELECT ON {', '.join(ALL_TABLES)} TO {q}"]


def bind_bench(conn: Connection, name: str, role: str) -> None:
    """Bench NAME's rows belong to ROLE (the owner acts; row-level security, r0004); its
    runs delivered so far go with it."""
    import sqlalchemy as sa

    conn.execute(sa.text(
        "INSERT INTO benches (name, db_role, first_seen_utc) VALUES (:n, :r, "
        "timezone('UTC', now())) ON CONFLICT (name) DO UPDATE SET db_role = EXCLUDED.db_role"),
        {"n": name, "r": role})
