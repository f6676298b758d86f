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

from bench.app.register import chain
from bench.app.register.store import (
    REMOTE_OPENERS,
    Account,
    AuthError,
    Calibration,
    Deviation,
    Equipment,
    Receipt,
    Register,
    RegisterError,
    Revision,
    RunEvent,
    RunRecord,
)

TIMEOUT_S = 30.0
VIA_ENV = "BENCH_NAME"      # how a bench names itself to the service (else its host name)
VIA_HEADER = "X-Ratebench-Via"      # who the person acts through (service.py records it)


class Reply(dict[str, object]):
    """One JSON object of the service's answer, read field by field with its type."""

    def text(self, key: str) -> str:
        return str(self[key])

    def opt(self, key: str) -> str | None:
        v = self.get(key)
        return None if v is None else str(v)

    def texts(self, key: str) -> tuple[str, ...]:
        v = self.get(key)
        return tuple(str(x) for x in v) if isinstance(v, list) else ()

    def items_of(self, key: str) -> list[Reply]:
        v = self.get(key)
        return [Reply(x) for x in v if isinstance(x, dict)] if isinstance(v, list) else []


def _reply(v: object) -> Reply:
    if not isinstance(v, dict):
        raise RegisterError(f"the register service answered {type(v).__name__}, not an object")
    return Reply(v)


def _replies(v: object) -> list[Reply]:
    return [_reply(x) for x in v] if isinstance(v, list) else []


def _account(d: Reply) -> Account:
    return Account(d.text("name"), d.text("full_name"), d.texts("roles"), d.opt("function"),
                   bool(d.get("active")), bool(d.get("must_change")),
                   d.opt("password_changed_utc"))


def _num(d: Reply, key: str) -> float | None:
    v = d.get(key)
    return float(v) if isinstance(v, int | float) else None


def _date(d: Reply, key: str) -> dt.date | None:
    v = d.opt(key)
    return dt.date.fromisoformat(v) if v else None


def _calibration(v: Reply) -> Calibration:
    return Calibration(v.text("certificate"), v.text("issuer"), _date(v, "calibrated_on"),
                       dt.date.fromisoformat(v.text("due")), v.opt("found"),
                       _num(v, "found_error"), _num(v, "found_error_u"),
                       v.text("recorded_utc"), v.text("recorded_by"))


def _equipment(d: Reply) -> Equipment:
    return Equipment(d.text("serial"), d.text("model"), d.opt("certificate"),
                     d.opt("issuer"), _date(d, "due"),
                     tuple(Deviation(v.text("reason"), dt.date.fromisoformat(v.text("expires")),
                                     v.text("recorded_by"), v.text("recorded_utc"),
                                     v.opt("revoked_utc"), v.opt("revoked_by"))
                           for v in d.items_of("deviations")),
                     bool(d.get("identity_only")),
                     tuple(_calibration(v) for v in d.items_of("calibrations")))


def _revision(d: Reply) -> Revision:
    rev = d.get("revision")
    return Revision(d.text("number"), int(rev) if isinstance(rev, int) else 0,
                    d.text("issued_utc"), d.text("signatory"), d.text("signatory_name"),
                    d.text("meaning"), d.opt("reason"), d.text("result_sha256"),
                    d.text("pdf_sha256"), d.text("dcc_sha256"), d.text("html_sha256"),
                    d.opt("withdrawn_utc"), d.opt("audit_digest"), d.opt("withdrawn_reason"),
                    d.opt("withdrawn_by"))


def _object(v: object) -> dict[str, object]:
    return {str(k): x for k, x in v.items()} if isinstance(v, dict) else {}


def _run_record(d: Reply) -> RunRecord:
    def strings(key: str) -> dict[str, str]:
        v = d.get(key)
        return {str(k): str(x) for k, x in v.items()} if isinstance(v, dict) else {}

    def events() -> tuple[RunEvent, ...]:
        return tuple(RunEvent(e.text("utc"), e.text("kind"), _object(e.get("detail")))
                     for e in d.items_of("events"))

    return RunRecord(d.text("uid"), d.text("bench"), d.opt("performer"), d.text("version"),
                     bool(d.get("simulated")), strings("inputs"),
                     tuple(dict(i) for i in d.items_of("items")), d.text("registered_utc"),
                     d.text("via"), d.opt("result_sha256"), d.opt("result"),
                     d.opt("result_utc"), strings("raw"), events())


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
        reg._signs = bool(_reply(reg._get("info")).get("signs_dcc"))
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

    def _send(self, req: urllib.request.Request) -> object:
        try:
            with urllib.request.urlopen(req, timeout=TIMEOUT_S) as r:  # noqa: S310
                answer: object = json.loads(r.read())
                return _reply(answer)["ok"]
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

    def _get(self, op: str) -> object:
        return self._send(urllib.request.Request(f"{self.url}/v1/{op}",
                                                 headers={VIA_HEADER: self.via}))

    def _call(self, op: str, **body: object) -> object:
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
        got = _reply(self._call("authenticate", name=name, password=password, role=role))
        self._tokens[name] = got.text("token")
        return _account(_reply(got.get("account")))

    def accounts(self) -> list[Account]:
        return [_account(a) for a in _replies(self._call("accounts"))]

    def account(self, name: str) -> Account | None:
        got = self._call("account", name=name)
        return None if got is None else _account(_reply(got))

    def add_account(self, by: Account, name: str, full_name: str, roles: Sequence[str],
                    password: str, function: str | None = None) -> Account:
        return _account(_reply(self._call(
            "add_account", token=self._token(by.name), name=name, full_name=full_name,
            roles=list(roles), password=password, function=function)))

    def change_password(self, name: str, old: str, new: str) -> None:
        self._call("change_password", name=name, old=old, new=new)

    def reset_password(self, by: Account, name: str, new: str) -> None:
        self._call("reset_password", token=self._token(by.name), name=name, password=new)

    def set_active(self, by: Account, name: str, active: bool) -> Account:
        return _account(_reply(self._call("set_active", token=self._token(by.name),
                                          name=name, active=active)))

    def set_role(self, by: Account, name: str, role: str, grant: bool) -> Account:
        return _account(_reply(self._call("set_role", token=self._token(by.name), name=name,
                                          role=role, grant=grant)))

    # -- settings and equipment -----------------------------------------------------------

    def setting(self, key: str) -> str | None:
        got = self._call("setting", key=key)
        return None if got is None else str(got)

    def int_setting(self, key: str) -> int:
        value = _reply(self._call("settings")).get(key)
        return int(value) if isinstance(value, int) else 0

    def set_setting(self, by: Account, key: str, value: str) -> None:
        self._call("set_setting", token=self._token(by.name), key=key, value=value)

    def equipment(self, serial: str | None = None) -> list[Equipment]:
        return [_equipment(e) for e in _replies(self._call("equipment", serial=serial))]

    def add_equipment(self, by: Account, serial: str, model: str, certificate: str | None,
                      issuer: str | None, due: dt.date | None, identity_only: bool = False,
                      calibrated_on: dt.date | None = None) -> None:
        self._call("add_equipment", token=self._token(by.name), serial=serial, model=model,
                   certificate=certificate, issuer=issuer,
                   due=due.isoformat() if due else None, identity_only=identity_only,
                   calibrated_on=calibrated_on.isoformat() if calibrated_on else None)

    def update_equipment(self, by: Account, serial: str, certificate: str, issuer: str,
                         due: dt.date, calibrated_on: dt.date | None = None,
                         found: str | None = None, found_error: float | None = None,
                         found_error_u: float | None = None) -> Calibration:
        return _calibration(_reply(self._call(
            "update_equipment", token=self._token(by.name), serial=serial,
            certificate=certificate, issuer=issuer, due=due.isoformat(),
            calibrated_on=calibrated_on.isoformat() if calibrated_on else None, found=found,
            found_error=found_error, found_error_u=found_error_u)))

    def revoke_deviation(self, by: Account, serial: str) -> int:
        got = self._call("revoke_deviation", token=self._token(by.name), serial=serial)
        return got if isinstance(got, int) else 0

    def withdraw(self, by: Account, number: str, reason: str) -> Revision:
        return _revision(_reply(self._call("withdraw", token=self._token(by.name),
                                           number=number, reason=reason)))

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
        return [_revision(r) for r in _replies(self._call("revisions", number=number))]

    def find_revision(self, sha256: str) -> Revision | None:
        got = self._call("find_revision", sha256=sha256)
        return None if got is None else _revision(_reply(got))

    def begin_issue(self, signatory: Account, number: str, revision: int = 0,
                    result_sha256: str = "") -> Receipt:
        got = _reply(self._call("begin_issue", token=self._token(signatory.name),
                                number=number, revision=revision,
                                result_sha256=result_sha256))
        seq = got.get("audit_seq")
        return Receipt(got.text("issued_utc"), seq if isinstance(seq, int) else 0,
                       got.text("audit_digest"))

    def issue(self, number: str, revision: int, signatory: Account,
              digests: Mapping[str, str], reason: str | None,
              detail: Mapping[str, object]) -> Revision:
        return _revision(_reply(self._call(
            "issue", token=self._token(signatory.name), number=number, revision=revision,
            digests=dict(digests), reason=reason, detail=dict(detail))))

    def append(self, actor: str, action: str, obj: str,
               detail: Mapping[str, object] | str = "") -> str:
        return str(self._call("append", token=self._token(actor), action=action, object=obj,
                              detail=detail if isinstance(detail, Mapping) else
                              {"detail": detail}))

    def audit_rows(self) -> list[dict[str, object]]:
        return [dict(r) for r in _replies(self._call("audit_rows"))]

    # -- runs (no person's token: the service records the bench it came through) ----------

    def register_run(self, uid: str, bench: str, performer: str | None, version: str,
                     simulated: bool, inputs: Mapping[str, str],
                     items: Sequence[Mapping[str, object]]) -> RunRecord:
        return _run_record(_reply(self._call(
            "register_run", uid=uid, bench=bench, performer=performer, version=version,
            simulated=simulated, inputs=dict(inputs), items=[dict(i) for i in items])))

    def run_session(self, uid: str, session: int, performer: str | None) -> None:
        self._call("run_session", uid=uid, session=session, performer=performer)

    def deliver_result(self, uid: str, kind: str, result: bytes, raw: Mapping[str, str],
                       reason: str | None = None) -> RunRecord:
        return _run_record(_reply(self._call(
            "deliver_result", uid=uid, kind=kind, raw=dict(raw), reason=reason,
            result=base64.b64encode(result).decode("ascii"))))

    def run_record(self, uid: str) -> RunRecord | None:
        got = self._call("run_record", uid=uid)
        return None if got is None else _run_record(_reply(got))

    def runs_using(self, serial: str) -> list[RunRecord]:
        return [_run_record(r) for r in _replies(self._call("runs_using", serial=serial))]

    def impact_assessed(self, by: Account, serial: str,
                        detail: Mapping[str, object]) -> str:
        return str(self._call("impact_assessed", token=self._token(by.name), serial=serial,
                              detail=dict(detail)))

    def audit_check(self) -> chain.ChainReport:
        got = _reply(self._call("audit_check"))
        entries = got.get("entries")
        return chain.ChainReport(entries if isinstance(entries, int) else 0,
                                 got.texts("problems"))


REMOTE_OPENERS["http"] = REMOTE_OPENERS["https"] = ServiceRegister.connect
