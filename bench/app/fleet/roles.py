"""The lab database's PostgreSQL roles: what a bench and the station may do (docs/station.md).

The lab's owner role creates and migrates the schema (`bench records init URL`) and
grants the benches' role what a delivery and a registration need: read everything,
insert and update the runs, figures, check values and certificate digests it registers
(a re-analysed run replaces its own rows), insert and update benches and their runs, and
only insert event lines (a line once delivered is never changed, not even by its bench);
no DDL. The station's role reads. Known limit: a bench role can update any bench's run
row, not only its own (PostgreSQL row security per bench would close it; not done).
"""

from __future__ import annotations

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
