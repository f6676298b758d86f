"""What the procedure kinds share: the prompt step, a whole-unit resume and the result
document's frame.

The plug-in interface itself (a kind and its parts) is `bench.core.registry.ProcedureKind`;
kinds are found by entry point.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, TypedDict

import msgspec

from bench.core import rundir_layout as layout
from bench.core.config import Config
from bench.core.lab import certificate_settings
from bench.core.plan import Plan, Step
from bench.core.stops import register
from bench.core.yamlfile import YamlValue
from bench.report.conformity import RULES
from bench.report.uncertainty_names import UNCERTAINTY_NAMING
from drivers.json_types import JsonLike, JsonScalar

# the engine and the journal for the hints only: `bench validate` loads the kinds (and this
# module) for their files alone
if TYPE_CHECKING:
    from bench.core.engine import RunContext
    from bench.core.events import Event
    from bench.core.journal import RunDir

#: a journal record as a reader holds it


def prompt(step: Step, ctx: RunContext) -> None:
    """The prompt step, the same for every kind: the operator reads it and answers."""
    ctx.prompt(step.describe)


def resume_whole(plan: Plan, run: RunDir) -> Plan:
    """What a --resume runs of `plan` (the units not done): all of it, for a kind that
    keeps no finer part of a unit (the rate ladder keeps each half already acquired)."""
    return plan


SCHEMA = "bench.result/1"



class RawFile(TypedDict):
    """result.json's `raw_files` entry: a raw file of the run, as hashed."""

    path: str
    sha256: str
    bytes: int


class RawHashes:
    """The SHA-256 of every raw file, hashed in threads from the moment this is made.

    A day's run holds gigabytes of raw capture: hashing them after the analysis added
    their reading time to every `bench run` and `bench analyze`. File reads and hashlib
    release the interpreter, so the hashes are taken while the analysis decodes.
    """

    def __init__(self, run: RunDir) -> None:
        self._run = run
        self._files = [p for p in sorted(layout.raw_root(run.path).rglob("*")) if p.is_file()]
        from concurrent.futures import ThreadPoolExecutor
        self._pool = ThreadPoolExecutor(max_workers=2, thread_name_prefix="sha256")
        register("raw-file hashing", lambda: self._pool.shutdown(False, cancel_futures=True),
                 "worker")
        self._hashes = [self._pool.submit(self._hash, p) for p in self._files]

    def _hash(self, path: Path) -> str:
        """The digest taken as the file was written by this process, when the file still
        has that length (RunDir.written_digest); else from the disk."""
        from bench.core.journal import sha256_file
        return self._run.written_digest(path) or sha256_file(path)

    def result(self) -> list[RawFile]:
        try:
            return [{"path": str(p.relative_to(self._run.path)), "sha256": h.result(),
                     "bytes": p.stat().st_size} for p, h in zip(self._files, self._hashes,
                                                                 strict=True)]
        finally:
            self._pool.shutdown(wait=False, cancel_futures=True)


class ProcedureFileRef(TypedDict):
    """result.json's `procedure_file`: the procedure the run followed, by name and digest."""

    name: str
    sha256: str


class RunDates(TypedDict):
    """result.json's `dates`: made, first started, last ended (None: not yet)."""

    created_utc: str
    started_utc: str | None
    completed_utc: str | None


class RunHeader(TypedDict):
    """What every kind's result.json says about the run, in the document's key order
    (bench/report/result_frame.py reads it back as ResultFrame)."""

    title: str
    run_dir: str
    procedure_file: ProcedureFileRef
    #: the stand file's identity keys it states, then the file, its digest, simulated
    stand: dict[str, JsonScalar]
    instruments: dict[str, dict[str, str]]
    dates: RunDates
    # the procedure's free-form blocks as its file states them (YAML values)
    conditions: dict[str, YamlValue]
    specification: dict[str, YamlValue] | None
    certificate: dict[str, YamlValue]
    sessions: int
    aborted: bool
    ended: str | None
    run_sessions: list[dict[str, str | int | None]]
    raw_files: list[RawFile]


def run_header(run: RunDir, cfg: Config, events: Sequence[Event],
               raw_hashes: RawHashes | None = None) -> RunHeader:
    """What every procedure kind's result.json says about the run (certificate header)."""
    from bench.core import events as ev  # the journal's records: not for `bench validate`
    meta = run.meta
    stand = cfg.stand_settings
    identities: dict[str, dict[str, str]] = {}
    for e in ev.of_kind(events, ev.Identity):
        identities[e.axis] = dict(e.instruments)
    from bench.core.journal import COMPLETED, session_endings
    starts = ev.of_kind(events, ev.SessionStarted)
    # the run ends as its last session did (a resume is a session of the same run)
    sessions = session_endings(events)
    last = sessions[-1] if sessions else None
    raw_files = (raw_hashes or RawHashes(run)).result()
    return RunHeader({
        "title": cfg.common.title,
        "run_dir": run.path.name,
        "procedure_file": {"name": meta["procedure_name"], "sha256": meta["procedure_sha256"]},
        "stand": {**{k: v for k, v in msgspec.structs.asdict(stand.identity).items()
                     if v is not None},
                  "file": Path(meta["stand_file"]).name,
                  "sha256": meta["stand_sha256"], "simulated": stand.simulated},
        "instruments": identities,
        "dates": {"created_utc": meta["created_utc"],
                  "started_utc": starts[0].utc if starts else None,
                  "completed_utc": last.ended_utc if last else None},
        "conditions": dict(cfg.common.conditions),
        "specification": (dict(cfg.common.specification)
                          if cfg.common.specification is not None else None),
        # the lab file the run copied when it started (bench.app.labfile's rule)
        "certificate": certificate_settings(run.procedure_file, dict(cfg.common.certificate)),
        "sessions": len(starts),
        "aborted": last is not None and last.ended != COMPLETED,
        "ended": last.ended if last else None,
        "run_sessions": [x.to_json() for x in sessions],
        "raw_files": raw_files,
    })


def result_document(run: RunDir, cfg: Config, events: Sequence[Event], *,
                    complete: bool, checks: Sequence[Mapping[str, JsonLike]], rule: str,
                    method: Mapping[str, JsonLike], raw_hashes: RawHashes | None = None,
                    **body: JsonLike) -> dict[str, object]:
    """result.json's frame: the verdict from the checks (each as the kind's codec encodes
    it), the run header, the rule and the method, then `body`: a kind's results given
    here by keyword (a plug-in kind's) or added after it."""
    if not complete:
        verdict = "incomplete"
    else:
        verdict = "fail" if any(c["verdict"] == "fail" for c in checks) else "pass"
    return {
        "schema": SCHEMA,
        "uncertainty_names": UNCERTAINTY_NAMING,
        "procedure": cfg.kind,
        "verdict": verdict,
        **run_header(run, cfg, events, raw_hashes),
        "decision_rule": rule,
        "decision_rule_text": RULES[rule],
        "method": method,
        "checks": checks,
        **body,
    }
