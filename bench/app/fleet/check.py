"""`bench records check RUN...`: what the lab database holds of a run, against its run
directory (the evidence): every event line (by its line number), the result, and the
SHA-256 of every raw file the result lists.

The run directory is read, never written; the lab database is read with the bench's
role. A difference is named by what and where (event line N, raw file PATH), so a line
deleted from events.jsonl or a raw byte changed after delivery is found, and a run not yet
wholly delivered says so (`bench records sync` delivers the rest).
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from pathlib import Path

import sqlalchemy as sa

from bench.app.fleet.codec import JournalLine, StoredResult, read_result, stored_line, stored_result
from bench.app.fleet.journal import new_lines
from bench.app.fleet.sync import LabLink, RunFacts
from bench.app.records import schema as s
from bench.core import rundir_layout as layout
from bench.core.journal import sha256_file

#: differences named one by one before the rest are counted
SHOWN = 5


@dataclass
class RunCheck:
    """One run's comparison: what was compared and every difference found."""

    run: str
    bench: str | None = None
    events: int = 0            # event lines compared
    raw_files: int = 0         # raw files whose digest was compared
    result: bool = False       # a result was compared
    differences: list[str] = field(default_factory=list)
    undelivered: int = 0       # lines the lab does not hold yet (after its last one)

    @property
    def equal(self) -> bool:
        return not self.differences and not self.undelivered

    def lines(self) -> list[str]:
        where = f" (bench {self.bench})" if self.bench else ""
        if self.equal:
            return [f"{self.run}{where}: equal: {self.events} event line(s), "
                    + (f"result, {self.raw_files} raw file digest(s)" if self.result
                       else "no result yet")]
        out = [f"{self.run}{where}: DIFFERS from what the lab database holds:"]
        out += [f"  {d}" for d in self.differences[:SHOWN]]
        if len(self.differences) > SHOWN:
            out.append(f"  ... and {len(self.differences) - SHOWN} more difference(s)")
        if self.undelivered:
            out.append(f"  {self.undelivered} event line(s) not delivered yet (`bench "
                       "records sync` delivers them)")
        return out


def _file_lines(run_path: Path) -> dict[int, JournalLine]:
    lines, _, _ = new_lines(run_path, 0, 0, 10 ** 9)
    return {x.seq: x for x in lines}


def check_run(link: LabLink, run_path: Path) -> RunCheck:
    """Compare one run directory with the lab database (`link`'s)."""
    facts = RunFacts.of(run_path)
    r, b, e = s.bench_runs.c, s.benches.c, s.bench_events.c
    out = RunCheck(run_path.name)
    with link.records().engine.connect() as conn:
        row = conn.execute(sa.select(r.id, r.last_seq, r.result, b.name.label("bench"))
                           .join(s.benches, b.id == r.bench_id)
                           .where(r.uid == facts.uid).order_by(r.id)).first()
        if row is None:
            out.differences.append(f"the lab database holds no run of uid {facts.uid}: "
                                   "never delivered (`bench records sync`)")
            return out
        held = {int(x.seq): stored_line(int(x.seq), x.body) for x in conn.execute(
            sa.select(e.seq, e.body).where(e.run_id == row.id).order_by(e.seq))}
    out.bench = str(row.bench)
    _compare_events(out, _file_lines(run_path), held, int(row.last_seq or 0))
    _compare_result(out, run_path, stored_result(row.result))
    return out


def _compare_events(out: RunCheck, lines: dict[int, JournalLine],
                    held: dict[int, JournalLine], last_seq: int) -> None:
    """The lab's lines against the file's, as a diff (a deleted or inserted line is one
    difference, not every line after it), named by the lab's line numbers."""
    out.events = len(held)
    out.undelivered = sum(1 for seq, x in lines.items() if seq > last_seq
                          and x.body is not None and seq not in held)
    theirs = sorted(held)
    mine = [seq for seq in sorted(lines) if seq <= max(last_seq, max(held, default=0))]
    a = [held[q].text for q in theirs]
    b = [lines[q].text for q in mine]
    for op, i1, i2, j1, j2 in difflib.SequenceMatcher(None, a, b, autojunk=False).get_opcodes():
        if op == "equal":
            continue
        if op in ("delete", "replace") and i2 - i1 != j2 - j1 or op == "delete":
            for k in range(i1, i2):
                if op == "delete" or k - i1 >= j2 - j1:
                    out.differences.append(
                        f"event line {theirs[k]} ({held[theirs[k]].name}): the lab database "
                        "holds it, the run directory does not (deleted?)")
        if op in ("insert", "replace"):
            for k in range(j1, j2):
                if op == "replace" and k - j1 < i2 - i1:
                    q = theirs[i1 + k - j1]
                    out.differences.append(
                        f"event line {q}: the run directory's line differs from the one "
                        f"delivered ({lines[mine[k]].name} here, {held[q].name} in the lab)")
                elif lines[mine[k]].body is not None:
                    out.differences.append(
                        f"event line {mine[k]} ({lines[mine[k]].name}): in the run "
                        "directory, not in the lab database")


def _mine(path: Path) -> StoredResult | str | None:
    """The run directory's result.json; None when there is none, else the reason it
    cannot be compared."""
    if not path.is_file():
        return None
    try:
        return read_result(path) or "unreadable"
    except (OSError, ValueError):
        return "unreadable"


def _compare_result(out: RunCheck, run_path: Path, lab: StoredResult | None) -> None:
    mine = _mine(run_path / layout.RESULT)
    if lab is None and mine is None:
        return
    out.result = True
    if lab is None:
        out.differences.append(f"{layout.RESULT}: in the run directory, not in the lab "
                               "database (`bench records sync`)")
    elif not isinstance(mine, StoredResult):
        out.differences.append(f"{layout.RESULT}: the lab database holds one, the run "
                               f"directory's is {'missing' if mine is None else mine}")
    elif mine.document != lab.document:
        out.differences.append(f"{layout.RESULT}: differs from the one delivered")
    if lab is None:
        return
    for entry in lab.raw_files:
        rel = entry.path
        f = run_path / rel
        out.raw_files += 1
        if not f.is_file():
            out.differences.append(f"raw file {rel}: missing from the run directory")
            continue
        digest = sha256_file(f)
        if digest != entry.sha256:
            out.differences.append(f"raw file {rel}: SHA-256 {digest[:16]}… in the run "
                                   f"directory, {str(entry.sha256)[:16]}… in the lab's "
                                   "result")
    named = lab.named
    raw = layout.raw_root(run_path)
    for f in sorted(p for p in raw.rglob("*") if p.is_file()) if raw.is_dir() else []:
        rel = str(f.relative_to(run_path))
        if rel not in named:
            out.differences.append(f"raw file {rel}: in the run directory, not in the lab's "
                                   "result")
