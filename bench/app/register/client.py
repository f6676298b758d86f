"""The register as a bench or station sees it on a lab server: every call goes to the
register service (service.py), which checks the person and acts in their name.

`Register.open("https://...")` returns a `ServiceRegister`, so `bench authorise`, `bench
run --operator`, `bench register ...`, `bench control --review` and the station use the
service through the same methods as a local SQLite register. A service that cannot be
reached refuses (RegisterError: exit 2 at the command line)."""

from __future__ import annotations

import base64
import datetime as dt
import json
import os
import socket
import urllib.error
import urllib.request
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from bench.app.register import chain
from bench.app.register.service import VIA_HEADER
from bench.app.register.store import (
    Account,
    AuthError,
    Deviation,
    Equipment,
    Register,
    RegisterError,
    Revision,
)

TIMEOUT_S = 30.0
VIA_ENV = "BENCH_NAME"      # how a bench names itself to the service (else its host name)


def _account(d: Any) -> Account:
    return Account(str(d["name"]), str(d["full_name"]), tuple(d["roles"]), d["function"],
                   bool(d["active"]), bool(d["must_change"]), d["password_changed_utc"])


def _equipment(d: Any) -> Equipment:
    return Equipment(d["serial"], d["model"], d["certificate"], d["issuer"],
                     dt.date.fromisoformat(d["due"]),
                     tuple(Deviation(v["reason"], dt.date.fromisoformat(v["expires"]),
                                     v["recorded_by"], v["recorded_utc"])
                           for v in d["deviations"]))


def _revision(d: Any) -> Revision:
    return Revision(**d)


class ServiceRegister(Register):
    """The lab's register through its service: the same methods, none of the authority."""

    def __init__(self, url: str, via: str | None = None) -> None:   # no engine: no database
        self.url = url.rstrip("/")
        self.pg = False
        self.via = via or os.environ.get(VIA_ENV) or f"bench on {socket.gethostname()}"
        self._tokens: dict[str, str] = {}
        self._pending = {}
        self._signs = False

    remote = True

    @classmethod
    def connect(cls, url: str, via: str | None = None) -> ServiceRegister:
        reg = cls(url, via)
        reg._signs = bool(reg._get("info").get("signs_dcc"))
        return reg

    def dcc_signer(self, signatory: Account) -> Callable[[bytes], bytes] | None:
        """The service signs the issued DCC with the lab's key (never on the bench)."""
        if not self._signs:
            return None
        token = self._token(signatory.name)

        def sign(data: bytes) -> bytes:
            got = self._call("sign_dcc", token=token,
                             xml=base64.b64encode(data).decode("ascii"))
            return base64.b64decode(str(got))

        return sign

    def _send(self, req: urllib.request.Request) -> Any:
        try:
            with urllib.request.urlopen(req, timeout=TIMEOUT_S) as r:  # noqa: S310
                return json.loads(r.read())["ok"]
        except urllib.error.HTTPError as e:
            try:
                body = json.loads(e.read())
            except ValueError:
                raise RegisterError(f"register service {self.url}: HTTP {e.code}") from None
            err = AuthError if body.get("kind") == "auth" else RegisterError
            raise err(str(body.get("error"))) from None
        except (urllib.error.URLError, OSError, ValueError, KeyError) as e:
            why = getattr(e, "reason", e)
            raise RegisterError(f"register service {self.url} cannot be reached: {why}") \
                from None

    def _get(self, op: str) -> Any:
        return self._send(urllib.request.Request(f"{self.url}/v1/{op}",
                                                 headers={VIA_HEADER: self.via}))

    def _call(self, op: str, **body: object) -> Any:
        return self._send(urllib.request.Request(
            f"{self.url}/v1/{op}", data=json.dumps(body).encode(), method="POST",
            headers={"Content-Type": "application/json", VIA_HEADER: self.via}))

    def _token(self, name: str) -> str:
        tok = self._tokens.get(name)
        if tok is None:
            raise AuthError(f"{name!r} has not authenticated to the register service")
        return tok

    def close(self) -> None:
        for tok in self._tokens.values():
            try:
                self._call("logout", token=tok)
            except RegisterError:
                pass
        self._tokens.clear()

    def _migrate(self) -> None:
        raise RegisterError("a register service is migrated by its owner on its database")

    def init(self, admin: str, full_name: str, password: str) -> bool:
        raise RegisterError("bench register init takes the database URL (the owner's), not "
                            "the service's")

    # -- accounts -------------------------------------------------------------------------

    def authenticate(self, name: str, password: str, role: str | None = None,
                     changing_password: bool = False) -> Account:
        if changing_password:
            raise RegisterError("through the service a password changes with "
                                "change_password")
        got = self._call("authenticate", name=name, password=password, role=role)
        self._tokens[name] = str(got["token"])
        return _account(got["account"])

    def accounts(self) -> list[Account]:
        return [_account(a) for a in self._call("accounts")]

    def account(self, name: str) -> Account | None:
        got = self._call("account", name=name)
        return None if got is None else _account(got)

    def add_account(self, by: Account, name: str, full_name: str, roles: Sequence[str],
                    password: str, function: str | None = None) -> Account:
        return _account(self._call("add_account", token=self._token(by.name), name=name,
                                   full_name=full_name, roles=list(roles), password=password,
                                   function=function))

    def change_password(self, name: str, old: str, new: str) -> None:
        self._call("change_password", name=name, old=old, new=new)

    def reset_password(self, by: Account, name: str, new: str) -> None:
        self._call("reset_password", token=self._token(by.name), name=name, password=new)

    def set_active(self, by: Account, name: str, active: bool) -> Account:
        return _account(self._call("set_active", token=self._token(by.name), name=name,
                                   active=active))

    def set_role(self, by: Account, name: str, role: str, grant: bool) -> Account:
        return _account(self._call("set_role", token=self._token(by.name), name=name,
                                   role=role, grant=grant))

    # -- settings and equipment -----------------------------------------------------------

    def setting(self, key: str) -> str | None:
        got = self._call("setting", key=key)
        return None if got is None else str(got)

    def int_setting(self, key: str) -> int:
        return int(self._call("settings")[key])

    def set_setting(self, by: Account, key: str, value: str) -> None:
        self._call("set_setting", token=self._token(by.name), key=key, value=value)

    def equipment(self, serial: str | None = None) -> list[Equipment]:
        return [_equipment(e) for e in self._call("equipment", serial=serial)]

    def add_equipment(self, by: Account, serial: str, model: str, certificate: str,
                      issuer: str, due: dt.date) -> None:
        self._call("add_equipment", token=self._token(by.name), serial=serial, model=model,
                   certificate=certificate, issuer=issuer, due=due.isoformat())

    def add_deviation(self, by: Account, serial: str, reason: str, expires: dt.date) -> None:
        self._call("add_deviation", token=self._token(by.name), serial=serial, reason=reason,
                   expires=expires.isoformat())

    # -- numbers, revisions, the trail ----------------------------------------------------

    def allocate(self, run_uid: str, prefix: str, actor: str) -> str:
        return str(self._call("allocate", token=self._token(actor), run_uid=run_uid,
                              prefix=prefix))

    def number_of_run(self, run_uid: str) -> str | None:
        got = self._call("number_of_run", run_uid=run_uid)
        return None if got is None else str(got)

    def revisions(self, number: str) -> list[Revision]:
        return [_revision(r) for r in self._call("revisions", number=number)]

    def find_revision(self, sha256: str) -> Revision | None:
        got = self._call("find_revision", sha256=sha256)
        return None if got is None else _revision(got)

    def begin_issue(self, signatory: Account, number: str) -> str:
        return str(self._call("begin_issue", token=self._token(signatory.name), number=number))

    def issue(self, number: str, revision: int, signatory: Account,
              digests: Mapping[str, str], reason: str | None,
              detail: Mapping[str, object]) -> Revision:
        return _revision(self._call("issue", token=self._token(signatory.name), number=number,
                                    revision=revision, digests=dict(digests), reason=reason,
                                    detail=dict(detail)))

    def append(self, actor: str, action: str, obj: str,
               detail: Mapping[str, object] | str = "") -> str:
        return str(self._call("append", token=self._token(actor), action=action, object=obj,
                              detail=detail if isinstance(detail, Mapping) else
                              {"detail": detail}))

    def audit_rows(self) -> list[dict[str, object]]:
        return list(self._call("audit_rows"))

    def audit_check(self) -> chain.ChainReport:
        got = self._call("audit_check")
        return chain.ChainReport(int(got["entries"]), tuple(got["problems"]))
