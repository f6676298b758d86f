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
from dataclasses import dataclass
from pathlib import Path
from typing import TypedDict, Unpack

import msgspec

REGISTER_NAME = "certificate-register.jsonl"


class Authorised(TypedDict, total=False):
    """Who authorised an issue and why: Issue's fields after the result's digest."""

    signatory: str | None
    function: str | None
    reason: str | None
    changes: tuple[str, ...]
    meaning: str | None
    register: str | None
    audit_digest: str | None
    audit_seq: int | None
    audit_entry: str | None
    issuer: tuple[tuple[str, str], ...]


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
    audit_seq: int | None = None      # the issue's first audit entry (issue 54), as the
    audit_entry: str | None = None    # documents state it: sequence number and SHA-256
    #: the issuer's identity as the lab register holds it (issue 54): (certificate key,
    #: text) for laboratory, address, code, accreditation, printed instead of the files'
    issuer: tuple[tuple[str, str], ...] = ()
    #: the run as the register holds it (issue 54): its uid and when the register first
    #: saw it, at the run's start; the issue is made from that record
    run_uid: str | None = None
    run_registered_utc: str | None = None

    @property
    def receipt(self) -> str | None:
        """The sentence each issued document carries (`bench register audit --receipts`
        finds it again), and the register's record of the run it was made from."""
        if self.audit_seq is None or not self.audit_entry:
            return None
        held = (f". Issued from the lab register's record of run {self.run_uid}, which the "
                f"register holds from the run's start ({self.run_registered_utc}): inputs, "
                "raw captures and result as measured" if self.run_uid else "")
        return (f"Lab register audit trail entry {self.audit_seq}, SHA-256 "
                f"{self.audit_entry}{held}")

    @property
    def issue_date(self) -> str:
        return self.issued_utc[:10]

    @property
    def draft(self) -> bool:
        """Not (yet) authorised: no date of issue, no authoriser."""
        return not self.issued_utc



def issue_line(issue: Issue) -> str:
    """An issue as its line of the register (keys sorted, as since the first issue)."""
    return json.dumps(msgspec.to_builtins(issue), sort_keys=True)


def issue_of(line: str | bytes) -> Issue:
    """One line of the register (msgspec.MsgspecError: not one, e.g. a torn last line)."""
    return msgspec.json.decode(line, type=Issue, strict=False)


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
            out.append(issue_of(line))
        except msgspec.MsgspecError:
            continue  # a torn last line from a crash: the earlier issues still stand
    return out


def next_issue(run_path: Path | None, base: str, when: dt.datetime | None,
               result_sha256: str | None = None, **authorised: Unpack[Authorised]) -> Issue:
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
        f.write(issue_line(issue) + "\n")
        f.flush()
        os.fsync(f.fileno())
