"""The lab register: who may sign, which standards are valid, which certificate numbers
exist, and the audit trail, in one database the lab controls (docs/register.md).

`Register.open(url)` (store.py) is the one way in; `bench register ...` (commands.py) is
its command line; `bench authorise` (bench/app/certificate/authorise.py) issues only
through it; PostgreSQL enforces the bench role's limits (pgsql.py); chain.py checks the
audit trail."""

from bench.app.register import client  # noqa: F401 - opens https:// registers (service)
from bench.app.register.store import (
    MEANING_ISSUE,
    Account,
    AuthError,
    Equipment,
    Register,
    RegisterError,
    Revision,
    redact,
)

__all__ = ["MEANING_ISSUE", "Account", "AuthError", "Equipment", "Register", "RegisterError",
           "Revision", "redact"]
