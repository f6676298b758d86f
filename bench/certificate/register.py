"""The run's certificate register: one number per issue, revisions that name what they replace.

ISO/IEC 17025 7.8.8: an amended certificate is a new document, uniquely identified, that
refers to the one it replaces. So every issue (the first `bench run`, each later
`bench analyze`) gets its own number and revision, appended to `certificate-register.jsonl`
in the run directory; the register is never rewritten, so the chain of issues survives.

Numbers: the laboratory's own (`certificate.number`) or `<prefix>-<date of completion>-<8
hex digits of the run's identity>`; revision 1 is the number itself, revision n >= 2 is
`<number>-R<n>`. The issue date is the date of authorisation: the moment the certificate is
issued under the named authorising signatory.
"""

from __future__ import annotations

import datetime as dt
import json
import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

REGISTER_NAME = "certificate-register.jsonl"


@dataclass(frozen=True)
class Issue:
    """One issue of a certificate."""

    number: str
    revision: int
    issued_utc: str
    replaces: str | None = None
    result_sha256: str | None = None

    @property
    def issue_date(self) -> str:
        return self.issued_utc[:10]

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


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
            d = json.loads(line)
            out.append(Issue(str(d["number"]), int(d["revision"]), str(d["issued_utc"]),
                             d.get("replaces"), d.get("result_sha256")))
        except (ValueError, KeyError, TypeError):
            continue  # a torn last line from a crash: the earlier issues still stand
    return out


def next_issue(run_path: Path | None, base: str, when: dt.datetime,
               result_sha256: str | None = None) -> Issue:
    """The issue that the next rendering will be: one revision after the last recorded."""
    previous = issues(run_path)
    revision = (previous[-1].revision + 1) if previous else 1
    stamp = when.astimezone(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    return Issue(numbered(base, revision), revision, stamp,
                 previous[-1].number if previous else None, result_sha256)


def record(run_path: Path, issue: Issue) -> None:
    """Append the issue to the register (one line, flushed to disk before returning)."""
    path = Path(run_path) / REGISTER_NAME
    with path.open("a", encoding="utf-8") as f:
        f.write(json.dumps(issue.to_dict(), sort_keys=True) + "\n")
        f.flush()
        os.fsync(f.fileno())
