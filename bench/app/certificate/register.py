"""The run's certificate register: who issued which revision, when and why.

ISO/IEC 17025 7.8.8: an amended certificate is a new document, uniquely identified, that
refers to the one it replaces and says why. `bench run` and `bench analyze` write drafts,
which are not issues and are not recorded; only `bench authorise` issues (bench/app/certificate/
authorise.py): it appends one line to `certificate-register.jsonl` in the run directory,
naming the authorising signatory, the time, the reason for a re-issue and what changed.
The register is never rewritten, so the chain of issues survives; each issued revision's
files are kept under `issued/<number>/` and never overwritten.

Numbers: the laboratory's own (`certificate.number`) or `<prefix>-<date of completion>-<8
hex digits of the run's identity>`; revision 1 is the number itself, revision n >= 2 is
`<number>-R<n>`. The issue date is the date of authorisation.
"""

from __future__ import annotations

import datetime as dt
import json
import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from drivers.json_types import JsonObject

REGISTER_NAME = "certificate-register.jsonl"


@dataclass(frozen=True)
class Issue:
    """One issue of a certificate."""

    number: str
    revision: int
    issued_utc: str
    replaces: str | None = None
    result_sha256: str | None = None
    signatory: str | None = None      # who authorised the issue (None: a draft)
    function: str | None = None       # their function in the laboratory
    reason: str | None = None         # why a revision was re-issued (7.8.8)
    changes: tuple[str, ...] = ()     # what differs from the revision it replaces
    meaning: str | None = None        # the signature's meaning ("authorised for issue")
    register: str | None = None       # the register that recorded the issue (URL)
    audit_digest: str | None = None   # its audit entry: the receipt of the issue

    @property
    def issue_date(self) -> str:
        return self.issued_utc[:10]

    @property
    def draft(self) -> bool:
        """Not (yet) authorised: no date of issue, no authoriser."""
        return not self.issued_utc

    def to_json(self) -> JsonObject:
        d = asdict(self)
        d["changes"] = list(self.changes)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Issue:
        return cls(str(d["number"]), int(d["revision"]), str(d["issued_utc"]),
                   d.get("replaces"), d.get("result_sha256"), d.get("signatory"),
                   d.get("function"), d.get("reason"),
                   tuple(str(c) for c in d.get("changes") or ()), d.get("meaning"),
                   d.get("register"), d.get("audit_digest"))


def numbered(base: str, revision: int) -> str:
    """The number of a revision: the base for the first issue, `<base>-R<n>` after it."""
    return base if revision <= 1 else f"{base}-R{revision}"


def issues(run_path: Path | None) -> list[Issue]:
    """Every issue recorded for the run, oldest first (none without a run directory)."""
    if run_path is None:
        return []
    path = Path(run_path) / REGISTER_NAME
    if not path.is_file():
        return []
    out = []
    for line in path.read_text(encoding="utf-8").splitlines():
        try:
            out.append(Issue.from_dict(json.loads(line)))
        except (ValueError, KeyError, TypeError):
            continue  # a torn last line from a crash: the earlier issues still stand
    return out


def next_issue(run_path: Path | None, base: str, when: dt.datetime | None,
               result_sha256: str | None = None, **authorised: Any) -> Issue:
    """The next revision after the last recorded: a draft when `when` is None, else the
    issue authorised then (signatory, function, reason, changes as keywords)."""
    previous = issues(run_path)
    revision = (previous[-1].revision + 1) if previous else 1
    stamp = when.astimezone(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ") if when else ""
    return Issue(numbered(base, revision), revision, stamp,
                 previous[-1].number if previous else None, result_sha256, **authorised)


def draft(run_path: Path | None, base: str) -> Issue:
    """The revision a draft would become if authorised now; not recorded."""
    return next_issue(run_path, base, None)


def record(run_path: Path, issue: Issue) -> None:
    """Append the issue to the register (one line, flushed to disk before returning)."""
    path = Path(run_path) / REGISTER_NAME
    with path.open("a", encoding="utf-8") as f:
        f.write(json.dumps(issue.to_json(), sort_keys=True) + "\n")
        f.flush()
        os.fsync(f.fileno())
