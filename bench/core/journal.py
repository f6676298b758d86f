"""The run directory: resolved inputs, an append-only event log, every raw byte.

A run directory is the evidence behind a certificate. The event log is JSON lines,
flushed and fsynced at every write, so a crash or a power cut loses at most the line
being written; raw instrument data goes to files of their own, as received.

    RUN_DIR/
      procedure.yaml  stand.yaml      the input files, byte for byte
      meta.json                       names, SHA-256 of the inputs, versions
      events.jsonl                    append-only event log (all sessions)
      raw/s<session>/<axis>-fog.bin   FOG bytes as received
      raw/s<session>/<axis>-counter.jsonl   every SCPI exchange, in order
      raw/s<session>/<axis>-drive.jsonl     drive readings (TPDO), commands, EMCY
      result.json, certificate.*      derived; `bench analyze` rebuilds them

The names are spelled in bench/core/rundir_layout.py, for every reader and writer.
"""

from __future__ import annotations

import datetime as dt
import errno
import hashlib
import os
import shutil
import threading
import uuid
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import IO

import msgspec

import bench
from bench.core import events as ev
from bench.core import rundir_layout as layout
from bench.core.events import Event
from bench.core.journal_codec import (
    RunMeta,
    encode_document,
    encode_event,
    read_events,
    read_meta,
)
from drivers.json_types import JsonLike


def sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def utc_now() -> str:
    return dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds")


class JournalError(OSError):
    """A run-directory file could not be written; the message names the file."""


def _write_error(path: Path, e: OSError) -> JournalError:
    why = e.strerror or str(e)
    if e.errno == errno.ENOSPC:
        why += " (the disk is full)"
    err = JournalError(e.errno or 0, f"cannot write {path}: {why}")
    err.filename = str(path)
    return err


class JsonLines:
    """An append-only JSON-lines file; `fsync=True` syncs every line to disk. It takes each
    line encoded (bench/core/journal_codec.py `encode_line`, `encode_event`)."""

    def __init__(self, path: Path, fsync: bool = False) -> None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            self._f: IO[str] = open(path, "a", encoding="utf-8")
        except OSError as e:
            raise _write_error(path, e) from e
        self.path = path
        self._fsync = fsync
        self._lock = threading.Lock()
        self.count = 0  # records written by this writer

    def write(self, line: str) -> None:
        with self._lock:
            if self._f.closed:
                return
            try:
                self._f.write(line)
                self._f.flush()
                if self._fsync:
                    os.fsync(self._f.fileno())
            except OSError as e:
                raise _write_error(self.path, e) from e
            self.count += 1

    def end_line(self) -> None:
        """End a torn last line, so the next record starts on a line of its own."""
        with self._lock:
            try:
                self._f.write("\n")
                self._f.flush()
            except OSError as e:
                raise _write_error(self.path, e) from e

    def sync(self) -> None:
        with self._lock:
            if not self._f.closed:
                try:
                    self._f.flush()
                    os.fsync(self._f.fileno())
                except OSError as e:
                    raise _write_error(self.path, e) from e

    def close(self) -> None:
        with self._lock:
            if self._f.closed:
                return
            try:
                self._f.flush()
                os.fsync(self._f.fileno())
            except OSError as e:
                raise _write_error(self.path, e) from e
            finally:
                try:
                    self._f.close()
                except OSError:
                    pass  # the flush above already failed and was reported


def units_done(events: Iterable[Event]) -> dict[str, int]:
    """Each unit done -> the session that completed it (the `unit_done` events; a unit
    measured again in a later session counts there)."""
    return {e.unit: e.session for e in events if isinstance(e, ev.UnitDone)}


#: how a session ended, as the journal shows it (`session_endings`)
COMPLETED, ABORTED, REFUSED = "completed", "aborted", "refused"
#: a session whose process is gone without writing how it ended (kill -9, a power cut)
KILLED = "killed or crashed"
#: the event a later process writes for a session it found ended that way
SESSION_LOST = "session_lost"


@dataclass(frozen=True)
class SessionEnding:
    """One session of a run (the first, or a `--resume`), as its events tell it: when it
    started and ended (UTC text), how it ended (None while it may still run), who
    performed it (the authenticated account, else None) and its process id."""

    session: int
    started_utc: str
    ended_utc: str | None
    ended: str | None
    performer: str | None
    os_user: str | None
    pid: int | None

    def to_json(self) -> dict[str, str | int | None]:
        return {"session": self.session, "started_utc": self.started_utc,
                "ended_utc": self.ended_utc, "ended": self.ended,
                "performer": self.performer, "os_user": self.os_user}


def session_endings(events: Iterable[Event]) -> list[SessionEnding]:
    """Every session of a run in order, with how it ended: `completed`, `aborted`
    (a fault, the operator, an unanswered prompt), `refused` (before anything moved),
    KILLED (a `session_lost` event a later process wrote, or a later session began
    without one) or None (no word yet: the last session, maybe still running).
    The run ends as its last session did."""
    starts: dict[int, ev.SessionStarted] = {}
    last_utc: dict[int, str] = {}
    ends: dict[int, tuple[str, str]] = {}
    for e in events:
        s, utc = e.session, e.utc
        if not s:
            continue
        if isinstance(e, ev.SessionStarted) and s not in starts:
            starts[s] = e
        if not isinstance(e, ev.SessionLost):
            last_utc[s] = utc
        if isinstance(e, ev.Completed):
            ends[s] = (COMPLETED, utc)
        elif isinstance(e, ev.Aborted | ev.Refused) and ends.get(s, ("",))[0] != COMPLETED:
            ends[s] = (ABORTED if isinstance(e, ev.Aborted) else REFUSED, utc)
        elif isinstance(e, ev.SessionLost) and s not in ends:
            ends[s] = (KILLED, e.last_utc or last_utc.get(s, utc))
    out: list[SessionEnding] = []
    numbers = sorted(starts)
    for i, s in enumerate(numbers):
        st = starts[s]
        ended: tuple[str | None, str | None] = ends.get(s, (None, None))
        if ended[0] is None and i + 1 < len(numbers):   # a later session began: it is gone
            ended = (KILLED, last_utc.get(s))
        out.append(SessionEnding(s, st.utc, ended[1], ended[0], st.performer_account,
                                 st.os_user or None, st.pid))
    return out


def fog_capture_starts(events: Iterable[Event]) -> dict[tuple[int, str], int]:
    """{(session, axis): the first sample index of that session's FOG capture}. A capture
    without the event starts at index 0 (a run from before the event existed)."""
    return {(e.session, e.axis): e.first_index for e in events
            if isinstance(e, ev.FogCapture) and e.first_index is not None}


def torn_tail_bytes(path: Path) -> int:
    """Bytes after the last newline: a line torn by a crash mid-write (0 if none)."""
    with open(path, "rb") as f:
        f.seek(0, os.SEEK_END)
        size = f.tell()
        back = min(size, 1 << 20)
        f.seek(size - back)
        tail = f.read()
    return len(tail) - (tail.rfind(b"\n") + 1)


class RunDir:
    """One run's directory. Create with `RunDir.create`, reopen with `RunDir(path)`."""

    PROCEDURE = layout.PROCEDURE
    STAND = layout.STAND
    LAB = layout.LAB

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not (self.path / layout.EVENTS).exists():
            raise FileNotFoundError(f"{self.path} is not a run directory (no events.jsonl)")
        self._events: JsonLines | None = None
        self.session = 0
        self._clock_now: Callable[[], float | None] = lambda: None
        #: what this process computed from the run's raw data while it ran (a kind's first
        #: look at a pair), for the final analysis to take instead of computing it again;
        #: never written: a resumed or re-analysed run starts without it
        self.memo: dict[str, object] = {}
        #: each raw file's (SHA-256 hex, bytes) as this process wrote it (a FOG capture
        #: hashed on its way to the file), so result.json need not read gigabytes back
        self._written: dict[Path, tuple[str, int]] = {}

    def remember_digest(self, path: Path | None, digest: tuple[str, int] | None) -> None:
        """A raw file's (SHA-256 hex, bytes) taken while it was written (nothing if None)."""
        if path is not None and digest is not None:
            self._written[Path(path).resolve()] = digest

    def written_digest(self, path: Path) -> str | None:
        """The SHA-256 remembered for `path`, while the file still has the length it was
        hashed at (a later session may have appended to it); else None: hash the disk."""
        known = self._written.get(Path(path).resolve())
        return known[0] if known is not None and known[1] == path.stat().st_size else None

    @classmethod
    def create(cls, out_dir: str | Path, procedure_path: Path, stand_path: Path,
               lab_path: Path | None = None, run_uid: str | None = None) -> RunDir:
        """A new run directory; `run_uid` made before it (the lab register names the run
        by it when the performer is authenticated), else here."""
        stamp = dt.datetime.now().strftime("%Y%m%d-%H%M%S")
        base = Path(out_dir) / f"{stamp}-{procedure_path.stem}"
        path, n = base, 1
        while path.exists():
            n += 1
            path = Path(f"{base}-{n}")
        path.mkdir(parents=True)
        shutil.copyfile(procedure_path, path / cls.PROCEDURE)
        shutil.copyfile(stand_path, path / cls.STAND)
        if lab_path is not None:  # the laboratory's settings as used (bench.core.lab)
            shutil.copyfile(lab_path, path / cls.LAB)
        meta: RunMeta = {
            "procedure_file": str(procedure_path),
            "procedure_name": procedure_path.name,
            "procedure_sha256": sha256_file(procedure_path),
            "stand_file": str(stand_path),
            "stand_sha256": sha256_file(stand_path),
            "created_utc": utc_now(),
            "bench_version": bench.__version__,
            "run_uid": run_uid or uuid.uuid4().hex,
        }
        (path / layout.META).write_text(encode_document(meta))
        (path / layout.EVENTS).touch()
        return cls(path)

    @property
    def meta(self) -> RunMeta:
        return read_meta(self.path / layout.META)

    @property
    def procedure_file(self) -> Path:
        return self.path / self.PROCEDURE

    @property
    def stand_file(self) -> Path:
        return self.path / self.STAND

    # -- sessions and events ------------------------------------------------------------
    def next_session(self) -> int:
        """The number the next `begin_session` gives (1 for a new run)."""
        return max((e.session for e in self.events()), default=0) + 1

    def begin_session(self, clock_now: Callable[[], float] | None = None) -> int:
        """Each `bench run` or `--resume` is a session with its own raw folder."""
        self.session = self.next_session()
        try:
            self.raw_dir.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise _write_error(self.raw_dir, e) from e
        log = self.path / layout.EVENTS
        torn = torn_tail_bytes(log)
        self._events = JsonLines(log, fsync=True)
        if torn:  # a crash mid-write: this session starts on a fresh line, not on the torn one
            self._events.end_line()
        if clock_now is not None:
            self._clock_now = clock_now
        if torn:
            self.write(ev.TornTail(file=layout.EVENTS, bytes=torn,
                                   note="a line cut short by a crash or power loss; kept "
                                        "as written, readers skip it"))
        return self.session

    @property
    def raw_dir(self) -> Path:
        return layout.raw_dir(self.path, self.session)

    def raw_path(self, name: str) -> Path:
        return self.raw_dir / name

    def write(self, record: Event) -> None:
        """Journal one event: the journal sets its frame (UTC, the stand clock, the
        session) and writes the line, flushed and fsynced."""
        if self._events is None:
            raise RuntimeError("begin_session() first")
        self._events.write(encode_event(msgspec.structs.replace(
            record, utc=utc_now(), t_s=self._clock_now(), session=self.session)))

    def events(self) -> list[Event]:
        """Every event of every session, each as its kind's record (bench/core/events.py)."""
        return read_events(self.path / layout.EVENTS)

    def completed_units(self) -> list[str]:
        return [e.unit for e in self.events() if isinstance(e, ev.UnitDone)]

    def close(self) -> None:
        if self._events is not None:
            self._events.close()

    # -- derived files ----------------------------------------------------------------
    def write_json(self, name: str, data: JsonLike) -> Path:
        """Write atomically: a reader never sees half a result.json."""
        target = self.path / name
        tmp = target.with_suffix(target.suffix + ".tmp")
        text = encode_document(data)
        try:
            tmp.write_text(text)
            os.replace(tmp, target)
        except OSError as e:
            tmp.unlink(missing_ok=True)
            raise _write_error(target, e) from e
        return target
