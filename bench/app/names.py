"""Names the CLI's parsers share with the modules that act on them: the default runs
folder and the lab register's roles. Standard library only (nothing at all), so that
bench/app/parsers.py can build `bench --help` without loading the records or the
register, and each name is still spelled once.
"""

from __future__ import annotations

#: the runs folder a command reads or writes when none is named (records.sqlite beside it)
DEFAULT_RUNS = "runs"
#: the lab register's roles (bench/app/register/schema.py; docs/register.md)
ROLES = ("operator", "reviewer", "signatory", "quality", "admin")


def resume_command(run_path: object, yes: bool) -> str:
    """The command that continues a run, as it works when typed: a run started unattended
    (`--yes`) is resumed so too (without it, a prompt read off no terminal aborts)."""
    return f"bench run --resume {run_path}" + (" --yes" if yes else "")
