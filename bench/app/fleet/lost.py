"""A run whose bench process is gone without journaling how it ended (kill -9, a crash, a
power cut): the bench says so itself, in the run's own event log, the next time it looks
at its runs folder (`bench run` starting, `bench records sync`), so the lab's page shows
the run ended ("killed or crashed", with its last step) instead of SILENT for ever.

SILENT then means what it says: a live process that stopped talking. The event is one
more journal line (`session_lost`, of the lost session), delivered like any other; the
run's evidence is untouched, and a `--resume` continues the run as before.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from bench.app.names import resume_command
from bench.core import events as ev
from bench.core import rundir_layout as layout
from bench.core.journal import KILLED, JsonLines, session_endings, torn_tail_bytes, utc_now
from bench.core.journal_codec import decode_event, encode_event, read_events


@dataclass(frozen=True)
class LostRun:
    """A run found with its last session's process gone and no end journaled."""

    run_path: Path
    session: int
    pid: int
    last_utc: str | None
    last_step: str | None
    yes: bool = False          # the session answered its prompts with --yes

    @property
    def line(self) -> str:
        step = f"; last step: {self.last_step}" if self.last_step else ""
        return (f"{self.run_path.name}: ended: {KILLED} (session {self.session}: its bench "
                f"process {self.pid} is gone and journaled no end{step}); "
                f"`{resume_command(self.run_path, self.yes)}` continues it")


def pid_exists(pid: int) -> bool:
    """Whether a process of this machine has the id `pid` (any program)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def process_alive(pid: int) -> bool:
    """Whether `pid` is a live process of this machine that is a bench (a pid reused by
    another program after a reboot is no bench)."""
    if pid == os.getpid():
        return True               # this process (a session run in-process)
    if not pid_exists(pid):
        return False
    try:
        cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return True             # no /proc here: trust the signal check
    return b"bench" in cmdline


def lost_session(run_path: Path) -> LostRun | None:
    """The run's last session when its process is gone without an end, else None (ended,
    still running, or from a bench that did not journal its pid)."""
    if _ended_by_its_last_line(run_path / layout.EVENTS):
        return None               # most runs of a folder: read 4 kB, not the whole log
    events = read_events(run_path / layout.EVENTS)
    endings = session_endings(events)
    if not endings:
        return None
    last = endings[-1]
    if last.ended is not None or last.pid is None or process_alive(last.pid):
        return None
    own = [e for e in events if e.session == last.session]
    step = ev.last(own, ev.StepStarted)
    yes = any(isinstance(e, ev.SessionStarted) and e.prompts == "--yes" for e in own)
    return LostRun(run_path, last.session, last.pid, own[-1].utc or None if own else None,
                   step.describe or None if step else None, yes)


def _ended_by_its_last_line(log: Path) -> bool:
    """The log's last whole line is a session's exit or a `session_lost`: nothing to find."""
    try:
        with open(log, "rb") as f:
            f.seek(0, os.SEEK_END)
            f.seek(max(0, f.tell() - 4096))
            tail = f.read()
    except OSError:
        return False
    lines = tail.split(b"\n")
    last = lines[-2] if len(lines) >= 2 else b""   # the last line that ends in a newline
    return isinstance(decode_event(last), ev.Exited | ev.SessionLost)


def journal_lost(found: LostRun, by: str) -> None:
    """Append the `session_lost` line to the run's event log (after a line torn by the
    crash, on a line of its own)."""
    log = found.run_path / layout.EVENTS
    torn = torn_tail_bytes(log)
    lines = JsonLines(log, fsync=True)
    try:
        if torn:
            lines.end_line()
        lines.write(encode_event(ev.SessionLost(
            utc=utc_now(), t_s=None, session=found.session, ended=KILLED, pid=found.pid,
            last_utc=found.last_utc, last_step=found.last_step, found_by=by)))
    finally:
        lines.close()


def mark_lost_runs(runs_dir: Path, by: str) -> list[LostRun]:
    """Journal every run of the runs folder whose bench process is gone without an end."""
    try:
        paths = sorted(p for p in Path(runs_dir).iterdir() if (p / layout.EVENTS).is_file())
    except (FileNotFoundError, NotADirectoryError):
        return []
    found = []
    for path in paths:
        try:
            lost = lost_session(path)
            if lost is not None:
                journal_lost(lost, by)
                found.append(lost)
        except OSError:
            continue        # a folder this process may not write: another bench's
    return found
