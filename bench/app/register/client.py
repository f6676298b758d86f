"""The register as a bench or station sees it on a lab server: every call goes to the
register service (service.py), which checks the person and acts in their name.

`Register.open("https://...")` returns a `ServiceRegister`, so `bench authorise`, `bench
run --operator`, `bench register ...`, `bench control --review` and the station use the
service through the same methods as a local SQLite register. A service that cannot be
reached refuses (RegisterError: exit 2 at the command line)."""

from __future__ import annotations

import datetime as dt
import os
import socket
import urllib.error
import urllib.request
from collections.abc import Callable, Mapping, Sequence
from typing import TypeVar

from bench.app.register import chain, wire
from bench.app.register.model import AuditDetail, AuditEntry, ItemRow
from bench.app.register.store import (
    REMOTE_OPENERS,
    Account,
    AuthError,
    Calibration,
    Equipment,
    Receipt,
    Register,
    RegisterError,
    Revision,
    RunRecord,
)

T = TypeVar("T")

TIMEOUT_S = 30.0
VIA_ENV = "BENCH_NAME"      # how a bench names itself to the service (else its host name)
VIA_HEADER = "X-Ratebench-Via"      # who the person acts through (service.py records it)


class ServiceRegister(Register):
    """The lab's register through its service: the same methods, none of the authority."""

    def __init__(self, url: str, via: str | None = None) -> None:   # no engine: no database
        self.url = url.rstrip("/")
        self.shown = self.url
        self.pg = False
        self.via = via or os.environ.get(VIA_ENV) or f"bench on {socket.gethostname()}"
        self._tokens: dict[str, str] = {}
        self._pending = {}
        self._signs = False

    remote = True

    @classmethod
    def connect(cls, url: str, via: str | None = None) -> ServiceRegister:
        reg = cls(url, via)
        info = reg._fetch(urllib.request.Request(f"{reg.url}/v1/info",
                                                 headers={VIA_HEADER: reg.via}))
        reg._signs = wire.answered("info", info, wire.Info).signs_dcc
        return reg

    def dcc_signer(self, signatory: Account) -> Callable[[bytes], bytes] | None:
        """The service signs the issued DCC with the lab's key (never on the bench)."""
        if not self._signs:
            return None
        token = self._token(signatory.name)

        def sign(data: bytes) -> bytes:
            return self._call("sign_dcc", wire.SignDcc(token=token, xml=data), bytes)

        return sign

    def _fetch(self, req: urllib.request.Request) -> bytes:
        """The service's answer's bytes (a refusal raised as its AuthError or
        RegisterError)."""
        try:
            with urllib.request.urlopen(req, timeout=TIMEOUT_S) as r:  # noqa: S310
                return bytes(r.read())
        except urllib.error.HTTPError as e:
            got = wire.refused(e.read())
            if got is None:
                raise RegisterError(f"register service {self.url}: HTTP {e.code}") from None
            raise (AuthError if got.kind == "auth" else RegisterError)(got.error) from None
        except (urllib.error.URLError, OSError, ValueError) as e:
            why = getattr(e, "reason", e)
            raise RegisterError(f"register service {self.url} cannot be reached: {why}") \
                from None

    def _post(self, op: str, body: wire.Body) -> bytes:
        return self._fetch(urllib.request.Request(
            f"{self.url}/v1/{op}", data=wire.request(body), method="POST",
            headers={"Content-Type": "application/json", VIA_HEADER: self.via}))

    def _call(self, op: str, body: wire.Body, want: type[T]) -> T:
        return wire.answered(op, self._post(op, body), want)

    def _maybe(self, op: str, body: wire.Body, want: type[T]) -> T | None:
        return wire.answered_or_none(op, self._post(op, body), want)

    def _do(self, op: str, body: wire.Body) -> None:
        self._post(op, body)

    def _token(self, name: str) -> str:
        tok = self._tokens.get(name)
        if tok is None:
            raise AuthError(f"{name!r} has not authenticated to the register service")
        return tok

    def close(self) -> None:
        for tok in self._tokens.values():
            try:
                self._do("logout", wire.Body(token=tok))
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
        got = self._call("authenticate", wire.Login(name=name, password=password, role=role),
                         wire.LoginAnswer)
        self._tokens[name] = got.token
        return got.account

    def accounts(self) -> list[Account]:
        return self._call("accounts", wire.Body(), list[Account])

    def account(self, name: str) -> Account | None:
        return self._maybe("account", wire.Named(name=name), Account)

    def add_account(self, by: Account, name: str, full_name: str, roles: Sequence[str],
                    password: str, function: str | None = None) -> Account:
        return self._call("add_account", wire.AddAccount(
            token=self._token(by.name), name=name, full_name=full_name, roles=list(roles),
            password=password, function=function), Account)

    def change_password(self, name: str, old: str, new: str) -> None:
        self._do("change_password", wire.ChangePassword(name=name, old=old, new=new))

    def reset_password(self, by: Account, name: str, new: str) -> None:
        self._do("reset_password", wire.ResetPassword(token=self._token(by.name), name=name,
                                                      password=new))

    def set_active(self, by: Account, name: str, active: bool) -> Account:
        return self._call("set_active", wire.SetActive(token=self._token(by.name), name=name,
                                                       active=active), Account)

    def set_role(self, by: Account, name: str, role: str, grant: bool) -> Account:
        return self._call("set_role", wire.SetRole(token=self._token(by.name), name=name,
                                                   role=role, grant=grant), Account)

    # -- settings and equipment -----------------------------------------------------------

    def setting(self, key: str) -> str | None:
        return self._maybe("setting", wire.Key(key=key), str)

    def int_setting(self, key: str) -> int:
        return self._call("settings", wire.Body(), dict[str, int]).get(key, 0)

    def set_setting(self, by: Account, key: str, value: str) -> None:
        self._do("set_setting", wire.SetSetting(token=self._token(by.name), key=key,
                                                value=value))

    def equipment(self, serial: str | None = None) -> list[Equipment]:
        return self._call("equipment", wire.EquipmentQuery(serial=serial), list[Equipment])

    def add_equipment(self, by: Account, serial: str, model: str, certificate: str | None,
                      issuer: str | None, due: dt.date | None, identity_only: bool = False,
                      calibrated_on: dt.date | None = None) -> None:
        self._do("add_equipment", wire.AddEquipment(
            token=self._token(by.name), serial=serial, model=model, certificate=certificate,
            issuer=issuer, due=due, identity_only=identity_only, calibrated_on=calibrated_on))

    def update_equipment(self, by: Account, serial: str, certificate: str, issuer: str,
                         due: dt.date, calibrated_on: dt.date | None = None,
                         found: str | None = None, found_error: float | None = None,
                         found_error_u: float | None = None) -> Calibration:
        return self._call("update_equipment", wire.UpdateEquipment(
            token=self._token(by.name), serial=serial, certificate=certificate, issuer=issuer,
            due=due, calibrated_on=calibrated_on, found=found, found_error=found_error,
            found_error_u=found_error_u), Calibration)

    def revoke_deviation(self, by: Account, serial: str) -> int:
        return self._call("revoke_deviation", wire.Serial(token=self._token(by.name),
                                                          serial=serial), int)

    def withdraw(self, by: Account, number: str, reason: str) -> Revision:
        return self._call("withdraw", wire.Withdraw(token=self._token(by.name), number=number,
                                                    reason=reason), Revision)

    def add_deviation(self, by: Account, serial: str, reason: str, expires: dt.date) -> None:
        self._do("add_deviation", wire.AddDeviation(token=self._token(by.name), serial=serial,
                                                    reason=reason, expires=expires))

    # -- numbers, revisions, the trail ----------------------------------------------------

    def allocate(self, run_uid: str, prefix: str, actor: str) -> str:
        return self._call("allocate", wire.Allocate(token=self._token(actor), run_uid=run_uid,
                                                    prefix=prefix), str)

    def number_of_run(self, run_uid: str) -> str | None:
        return self._maybe("number_of_run", wire.RunUid(run_uid=run_uid), str)

    def revisions(self, number: str) -> list[Revision]:
        return self._call("revisions", wire.Number(number=number), list[Revision])

    def find_revision(self, sha256: str) -> Revision | None:
        return self._maybe("find_revision", wire.Digest(sha256=sha256), Revision)

    def begin_issue(self, signatory: Account, number: str, revision: int = 0,
                    result_sha256: str = "") -> Receipt:
        return self._call("begin_issue", wire.BeginIssue(
            token=self._token(signatory.name), number=number, revision=revision,
            result_sha256=result_sha256), Receipt)

    def issue(self, number: str, revision: int, signatory: Account,
              digests: Mapping[str, str], reason: str | None,
              detail: AuditDetail) -> Revision:
        return self._call("issue", wire.Issue(
            token=self._token(signatory.name), number=number, revision=revision,
            digests=dict(digests), reason=reason, detail=dict(detail)), Revision)

    def append(self, actor: str, action: str, obj: str, detail: AuditDetail | str = "") -> str:
        return self._call("append", wire.Append(
            token=self._token(actor), action=action, obj=obj,
            detail=dict(detail) if isinstance(detail, Mapping) else {"detail": detail}), str)

    def audit_rows(self) -> list[AuditEntry]:
        return self._call("audit_rows", wire.Body(), list[AuditEntry])

    # -- runs (no person's token: the service records the bench it came through) ----------

    def register_run(self, uid: str, bench: str, performer: str | None, version: str,
                     simulated: bool, inputs: Mapping[str, str],
                     items: Sequence[ItemRow]) -> RunRecord:
        return self._call("register_run", wire.RegisterRun(
            uid=uid, bench=bench, performer=performer, version=version, simulated=simulated,
            inputs=dict(inputs), items=[dict(i) for i in items]), RunRecord)

    def run_session(self, uid: str, session: int, performer: str | None) -> None:
        self._do("run_session", wire.RunSession(uid=uid, session=session, performer=performer))

    def deliver_result(self, uid: str, kind: str, result: bytes, raw: Mapping[str, str],
                       reason: str | None = None) -> RunRecord:
        return self._call("deliver_result", wire.DeliverResult(
            uid=uid, kind=kind, raw=dict(raw), reason=reason, result=result), RunRecord)

    def run_record(self, uid: str) -> RunRecord | None:
        return self._maybe("run_record", wire.Uid(uid=uid), RunRecord)

    def runs_using(self, serial: str) -> list[RunRecord]:
        return self._call("runs_using", wire.Serial(serial=serial), list[RunRecord])

    def impact_assessed(self, by: Account, serial: str, detail: AuditDetail) -> str:
        return self._call("impact_assessed", wire.ImpactAssessed(
            token=self._token(by.name), serial=serial, detail=dict(detail)), str)

    def audit_check(self) -> chain.ChainReport:
        return self._call("audit_check", wire.Body(), chain.ChainReport)


REMOTE_OPENERS["http"] = REMOTE_OPENERS["https"] = ServiceRegister.connect
