"""Receipts of the audit trail held outside the register (issue 54): what customers and
run directories keep of each issue, checked against the chain.

An owner who rewrites the trail and its head consistently, or truncates both, passes the
chain's own check (chain.py); the receipts do not move with it. Each issued HTML and DCC
states its issue's first entry ("Lab register audit trail entry N, SHA-256 D"), and each
run's `certificate-register.jsonl` keeps that entry and the issue's own (`audit_digest`).
A receipt whose entry is gone, or whose sequence number now holds another digest, is found.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import msgspec

from bench.app.register.model import AuditEntry

#: the sentence an issued document carries (bench/app/certificate/register.Issue.receipt)
RECEIPT = re.compile(rb"Lab register audit trail entry (\d+), SHA-256 ([0-9a-f]{64})")
DOCUMENTS = ("*.html", "*.dcc.xml")
REGISTER_COPY = "certificate-register.jsonl"


@dataclass(frozen=True)
class ReceiptReport:
    checked: int
    files: int
    problems: tuple[str, ...]

    @property
    def ok(self) -> bool:
        return not self.problems


def _found(folders: Sequence[str | Path]) -> Iterable[tuple[Path, int | None, str]]:
    """(file, sequence number or None, digest) for every receipt under the folders."""
    from bench.app.certificate.register import issue_of

    for folder in folders:
        root = Path(folder)
        for path in sorted(root.rglob(REGISTER_COPY)):
            for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
                try:
                    issue = issue_of(line)
                except msgspec.MsgspecError:
                    continue    # a torn last line: the earlier receipts still count
                if issue.audit_seq is not None and issue.audit_entry is not None:
                    yield path, issue.audit_seq, issue.audit_entry
                if issue.audit_digest is not None:
                    yield path, None, issue.audit_digest
        for pattern in DOCUMENTS:
            for path in sorted(root.rglob(pattern)):
                for m in RECEIPT.finditer(path.read_bytes()):
                    yield path, int(m.group(1)), m.group(2).decode()


def check_receipts(rows: Sequence[AuditEntry],
                   folders: Sequence[str | Path]) -> ReceiptReport:
    by_seq = {r.seq: r.digest for r in rows}
    digests = set(by_seq.values())
    problems: list[str] = []
    files: set[Path] = set()
    checked = 0
    for path, seq, digest in _found(folders):
        files.add(path)
        checked += 1
        if seq is None:
            if digest not in digests:
                problems.append(f"{path}: the issue's entry {digest[:16]}... is not in the "
                                "trail")
            continue
        held = by_seq.get(seq)
        if held != digest:
            problems.append(f"{path}: entry {seq} SHA-256 {digest[:16]}... is "
                            + ("missing from the trail (truncated?)" if held is None else
                               f"not the trail's entry {seq} ({held[:16]}...): the trail "
                               "was rewritten or forked"))
    return ReceiptReport(checked, len(files), tuple(problems))
