"""Which lab file a command uses: one rule, for every command (docs/station.md, "The lab
file: one rule").

- A run's own commands (`bench run --resume`, `bench analyze`, `bench records sync`,
  `bench records check`) use the copy the run made when it started (RUN/lab.yaml): the
  run is continued, analysed and delivered under the lab it was measured under
  (`bench authorise` resolves its register itself: its --lab, else the run's copy).
- Every other command: `--lab FILE`, else `$BENCH_LAB_SETTINGS`; `bench run` also reads
  the procedure's `certificate: {lab: FILE}`.
- Two of these that name different lab files (not the same file, not the same bytes)
  refuse: the command would write under one lab and report under another.

The lab file names the register (`register:`) and the records (`records:`); a runs
folder's own lab.yaml is not read.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from bench.core import rundir_layout as layout

ENV = "BENCH_LAB_SETTINGS"


class LabChoiceError(ValueError):
    """Two lab files named for one command, or one that does not exist."""


def _same(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve() or a.read_bytes() == b.read_bytes()
    except OSError:
        return False


def choose(named: Sequence[tuple[str, str | Path | None]]) -> Path | None:
    """The first lab file named, in the order given (`(where, path)` pairs: `--lab`, the
    procedure's, the environment's); LabChoiceError when one does not exist or two
    differ."""
    given = [(where, Path(os.path.expanduser(str(p)))) for where, p in named if p]
    for where, p in given:
        if not p.is_file():
            raise LabChoiceError(f"the lab file {p} ({where}) does not exist")
    for where, p in given[1:]:
        first_where, first = given[0]
        if not _same(first, p):
            raise LabChoiceError(
                f"two lab files for one command: {first} ({first_where}) and {p} ({where}); "
                "name one (docs/station.md, 'The lab file: one rule')")
    return given[0][1] if given else None


def for_command(lab: str | Path | None, procedure_lab: Path | None = None) -> Path | None:
    """A command that is not a run's own: `--lab`, else the procedure's, else
    $BENCH_LAB_SETTINGS; any two that differ refuse."""
    return choose([("--lab", lab),
                   ("the procedure's certificate: {lab: ...}", procedure_lab),
                   (f"${ENV}", os.environ.get(ENV) or None)])


def for_run(run_path: Path, lab: str | Path | None = None) -> Path | None:
    """A run's own command: the run's copy; a `--lab` that differs from it refuses. A run
    that copied none (it started without a lab file) takes the command's rule."""
    copy = Path(run_path) / layout.LAB
    if copy.is_file():
        return choose([("the run's copy", copy), ("--lab", lab)])
    return for_command(lab)
