"""What the procedure kinds share: the prompt step, a whole-unit resume and the result
document's frame.

The plug-in interface itself (a kind and its parts) is `bench.core.registry.ProcedureKind`;
kinds are found by entry point.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import msgspec

from bench.core import rundir_layout as layout
from bench.core.config import Config
from bench.core.lab import certificate_settings
from bench.core.plan import Plan, Step
from bench.core.stops import register
from bench.report.conformity import RULES
from bench.report.uncertainty_names import UNCERTAINTY_NAMING
from drivers.json_types import JsonLike

# the engine and the journal for the hints only: `bench validate` loads the kinds (and this
# module) for their files alone
# and the result's codec likewise (it reads back through the analysis's number checks, so
# numpy): it is imported where a result is made
if TYPE_CHECKING:
    from bench.core.engine import RunContext
    from bench.core.events import Event
    from bench.core.journal import RunDir
    from bench.report.codec import KindResult, RawFile, ResultHead, ResultPart


def prompt(step: Step, ctx: RunContext) -> None:
    """The prompt step, the same for every kind: the operator reads it and answers."""
    ctx.prompt(step.describe)


def resume_whole(plan: Plan, run: RunDir) -> Plan:
    """What a --resume runs of `plan` (the units not done): all of it, for a kind that
    keeps no finer part of a unit (the rate ladder keeps each half already acquired)."""
    return plan


SCHEMA = "bench.result/1"



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
        from bench.report.codec import RawFile
        try:
            return [RawFile(str(p.relative_to(self._run.path)), h.result(), p.stat().st_size)
                    for p, h in zip(self._files, self._hashes, strict=True)]
        finally:
            self._pool.shutdown(wait=False, cancel_futures=True)


def result_head(run: RunDir, cfg: Config, events: Sequence[Event], *, complete: bool,
                checks: Sequence[ResultPart], rule: str, method: ResultPart,
                raw_hashes: RawHashes | None = None) -> ResultHead:
    """result.json's frame: the verdict from the checks (each the kind's Struct), the run
    header (the certificate's), the rule and the method."""
    from bench.core import events as ev  # the journal's records: not for `bench validate`
    from bench.core.journal import COMPLETED, session_endings
    from bench.report.codec import ProcedureFileRef, ResultHead, RunDates
    if not complete:
        verdict = "incomplete"
    else:
        verdict = "fail" if any(_verdict(c) == "fail" for c in checks) else "pass"
    meta = run.meta
    stand = cfg.stand_settings
    identities: dict[str, dict[str, str]] = {}
    for e in ev.of_kind(events, ev.Identity):
        identities[e.axis] = dict(e.instruments)
    starts = ev.of_kind(events, ev.SessionStarted)
    # the run ends as its last session did (a resume is a session of the same run)
    sessions = session_endings(events)
    last = sessions[-1] if sessions else None
    return ResultHead(
        schema=SCHEMA, uncertainty_names=UNCERTAINTY_NAMING, procedure=cfg.kind,
        verdict=verdict, title=cfg.common.title, run_dir=run.path.name,
        procedure_file=ProcedureFileRef(meta["procedure_name"], meta["procedure_sha256"]),
        stand={**{k: v for k, v in msgspec.structs.asdict(stand.identity).items()
                  if v is not None},
               "file": Path(meta["stand_file"]).name,
               "sha256": meta["stand_sha256"], "simulated": stand.simulated},
        instruments=identities,
        dates=RunDates(meta["created_utc"], starts[0].utc if starts else None,
                       last.ended_utc if last else None),
        conditions=dict(cfg.common.conditions),
        specification=(dict(cfg.common.specification)
                       if cfg.common.specification is not None else None),
        # the lab file the run copied when it started (bench.app.labfile's rule)
        certificate=certificate_settings(run.procedure_file, dict(cfg.common.certificate)),
        sessions=len(starts),
        aborted=last is not None and last.ended != COMPLETED,
        ended=last.ended if last else None,
        run_sessions=[x.to_json() for x in sessions],
        raw_files=(raw_hashes or RawHashes(run)).result(),
        decision_rule=rule, decision_rule_text=RULES[rule], method=method,
        checks=tuple(checks))


def _verdict(check: ResultPart) -> JsonLike:
    """A check's verdict (a plug-in kind's check may be JSON values)."""
    found: JsonLike = (check.get("verdict") if isinstance(check, Mapping)
                       else getattr(check, "verdict", None))
    return found


def result_document(run: RunDir, cfg: Config, events: Sequence[Event], *,
                    complete: bool, checks: Sequence[ResultPart], rule: str,
                    method: ResultPart, raw_hashes: RawHashes | None = None,
                    **body: JsonLike) -> KindResult[dict[str, JsonLike]]:
    """A result whose body is JSON values given by keyword (a plug-in kind's; the kinds
    here give their body's Struct to `KindResult` beside `result_head`)."""
    from bench.report.codec import KindResult
    return KindResult(result_head(run, cfg, events, complete=complete, checks=checks,
                                  rule=rule, method=method, raw_hashes=raw_hashes), body)
