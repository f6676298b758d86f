"""The audit trail's hash chain (ISO/IEC 17025 8.4, 7.11.2: records protected against
change): each entry's digest covers the entry and the digest before it, so an entry
altered anywhere changes every digest after it, and the head (the last entry's seq and
digest, kept apart by the register's own append) shows entries removed from the end.

The same text is hashed by PostgreSQL's `reg_audit_append` (bench/app/register/pgsql.py)
and by the SQLite path in Python: fields joined by a newline, UTF-8, SHA-256, hex."""

from __future__ import annotations

import hashlib
from collections.abc import Iterable
from dataclasses import dataclass

from bench.app.register.model import AuditEntry

GENESIS = "0" * 64


def entry_digest(prev: str, seq: int, utc: str, actor: str, action: str, obj: str,
                 detail: str, db_user: str) -> str:
    text = "\n".join((prev, str(seq), utc, actor, action, obj, detail, db_user))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


@dataclass(frozen=True)
class ChainReport:
    entries: int
    problems: tuple[str, ...]

    @property
    def ok(self) -> bool:
        return not self.problems


def check_chain(rows: Iterable[AuditEntry], head: tuple[int, str] | None) -> ChainReport:
    """Every entry's digest recomputed and linked to the one before; the last one compared
    with the head. Returns every problem found (none: the chain is whole)."""
    problems: list[str] = []
    prev, expect_seq, n = GENESIS, 1, 0
    for r in rows:
        n += 1
        seq = r.seq
        if seq != expect_seq:
            problems.append(f"entry {expect_seq}" + (f"..{seq - 1}" if seq - 1 > expect_seq
                                                      else "") + " missing")
        if r.prev_digest != prev:
            problems.append(f"entry {seq}: does not follow the entry before it "
                            f"(prev_digest {r.prev_digest[:12]}..., expected "
                            f"{prev[:12]}...)")
        want = entry_digest(r.prev_digest, seq, r.utc, r.actor, r.action, r.object, r.detail,
                            r.db_user)
        if want != r.digest:
            problems.append(f"entry {seq} ({r.action} {r.object}, {r.utc}): altered "
                            f"(its content gives {want[:12]}..., it records "
                            f"{r.digest[:12]}...)")
        prev, expect_seq = r.digest, seq + 1
    if head is None:
        if n:
            problems.append("the chain's head is missing")
    elif head != (expect_seq - 1, prev):
        problems.append(f"the head records entry {head[0]} ({head[1][:12]}...)"
                        f" but the trail ends at entry {expect_seq - 1} ({prev[:12]}...): "
                        "entries removed from its end, or the head rewritten")
    return ChainReport(n, tuple(problems))
