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
import json
from dataclasses import dataclass, field
from pathlib import Path

import sqlalchemy as sa

from bench.app.fleet.journal import new_lines
from bench.app.fleet.sync import LabLink, RunFacts
from bench.app.records import schema as s
from bench.core import rundir_layout as layout
from bench.core.events import name_of
from bench.core.journal import sha256_file
from drivers.json_types import JsonObject

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


def _file_lines(run_path: Path) -> dict[int, JsonObject | None]:
    lines, _, _ = new_lines(run_path, 0, 0, 10 ** 9)
    return {x.seq: x.event for x in lines}


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
        held = {int(x.seq): x.body for x in conn.execute(
            sa.select(e.seq, e.body).where(e.run_id == row.id).order_by(e.seq))}
    out.bench = str(row.bench)
    _compare_events(out, _file_lines(run_path), held, int(row.last_seq or 0))
    lab_result = row.result if isinstance(row.result, dict) else None
    _compare_result(out, run_path, lab_result)
    return out


def _compare_events(out: RunCheck, lines: dict[int, JsonObject | None],
                    held: dict[int, JsonObject], last_seq: int) -> None:
    """The lab's lines against the file's, as a diff (a deleted or inserted line is one
    difference, not every line after it), named by the lab's line numbers."""
    out.events = len(held)
    out.undelivered = sum(1 for seq, ev in lines.items() if seq > last_seq and ev is not None
                          and seq not in held)
    theirs = sorted(held)
    mine = [seq for seq in sorted(lines) if seq <= max(last_seq, max(held, default=0))]
    a = [_text(held[q]) for q in theirs]
    b = [_text(lines[q]) for q in mine]
    for op, i1, i2, j1, j2 in difflib.SequenceMatcher(None, a, b, autojunk=False).get_opcodes():
        if op == "equal":
            continue
        if op in ("delete", "replace") and i2 - i1 != j2 - j1 or op == "delete":
            for k in range(i1, i2):
                if op == "delete" or k - i1 >= j2 - j1:
                    out.differences.append(
                        f"event line {theirs[k]} ({_kind(held[theirs[k]])}): the lab database "
                        "holds it, the run directory does not (deleted?)")
        if op in ("insert", "replace"):
            for k in range(j1, j2):
                if op == "replace" and k - j1 < i2 - i1:
                    q = theirs[i1 + k - j1]
                    out.differences.append(
                        f"event line {q}: the run directory's line differs from the one "
                        f"delivered ({_kind(lines[mine[k]])} here, {_kind(held[q])} in the lab)")
                elif lines[mine[k]] is not None:
                    out.differences.append(
                        f"event line {mine[k]} ({_kind(lines[mine[k]])}): in the run "
                        "directory, not in the lab database")


def _text(event: JsonObject | None) -> str:
    return json.dumps(event, sort_keys=True) if event is not None else "\0torn"


def _kind(event: JsonObject | None) -> str:
    return name_of(event) if event is not None else "not an event"


def _compare_result(out: RunCheck, run_path: Path, lab: JsonObject | None) -> None:
    path = run_path / layout.RESULT
    try:
        mine = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else None
    except (OSError, ValueError):
        mine = "unreadable"
    if lab is None and mine is None:
        return
    out.result = True
    if lab is None:
        out.differences.append(f"{layout.RESULT}: in the run directory, not in the lab "
                               "database (`bench records sync`)")
    elif mine is None or mine == "unreadable":
        out.differences.append(f"{layout.RESULT}: the lab database holds one, the run "
                               f"directory's is {'missing' if mine is None else 'unreadable'}")
    elif mine != lab:
        out.differences.append(f"{layout.RESULT}: differs from the one delivered")
    if lab is None:
        return
    listed = lab.get("raw_files")
    for entry in listed if isinstance(listed, list) else []:
        if not isinstance(entry, dict) or not isinstance(entry.get("path"), str):
            continue
        rel = str(entry["path"])
        f = run_path / rel
        out.raw_files += 1
        if not f.is_file():
            out.differences.append(f"raw file {rel}: missing from the run directory")
            continue
        digest = sha256_file(f)
        if digest != entry.get("sha256"):
            out.differences.append(f"raw file {rel}: SHA-256 {digest[:16]}… in the run "
                                   f"directory, {str(entry.get('sha256'))[:16]}… in the lab's "
                                   "result")
    named = {str(x.get("path")) for x in listed if isinstance(x, dict)} \
        if isinstance(listed, list) else set()
    raw = layout.raw_root(run_path)
    for f in sorted(p for p in raw.rglob("*") if p.is_file()) if raw.is_dir() else []:
        rel = str(f.relative_to(run_path))
        if rel not in named:
            out.differences.append(f"raw file {rel}: in the run directory, not in the lab's "
                                   "result")
