"""`bench register serve`: the lab's register service (issue 53, docs/register.md).

Why a service: PostgreSQL cannot verify an argon2id password, lock an account after
failed guesses or audit a failed login, so a database role that may issue can issue in
anyone's name. This process is the one holder of that role: it checks each person's
password where the lockout applies (store.Register.authenticate), hands the client a
short-lived token bound to the authenticated account, and does each change in that
account's name with its own clock. The benches' and the station's database roles only
read (pgsql.read_grants); they reach the register's authority through here.

The protocol is JSON over HTTP: `POST /v1/<operation>` with a JSON object, answered
with `{"ok": value}` or `{"error": text, "kind": "auth"|"register"}`. A client says who
it is with the header `X-Ratebench-Via` ("bench hall-1"); every audit entry the request
writes records that and the client's address. Passwords are accepted over plain HTTP
only from the loopback address; off this machine the service sits behind a TLS proxy.
"""

from __future__ import annotations

import secrets
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, TypeVar

from flask import Flask, request
from werkzeug.wrappers import Response

from bench.app.register import wire
from bench.app.register.client import VIA_HEADER
from bench.app.register.store import (
    ACTING_VIA,
    SETTING_DEFAULTS,
    SIGNING_SETTING,
    Account,
    AuthError,
    Register,
    RegisterError,
)

if TYPE_CHECKING:
    from bench.core.lab import Signing

B = TypeVar("B", bound=wire.Body)

TOKEN_S = 15 * 60.0         # a login is good this long after its last use (a station's idle)
#: audit entries a bench or station may add in an authenticated person's name
CLIENT_ACTIONS = ("run started by", "control review", "station login", "station logout",
                  "station session ended", "station sign refused")
PASSWORD_OPS = ("authenticate", "change_password", "add_account", "reset_password")


class Tokens:
    """Logins of this process: token -> (account name, expiry). A token names an account;
    its roles are read again from the register at each use."""

    def __init__(self, lifetime_s: float = TOKEN_S) -> None:
        self._by_token: dict[str, tuple[str, float]] = {}
        self._lock = threading.Lock()
        self.lifetime_s = lifetime_s

    def start(self, name: str) -> str:
        token = secrets.token_urlsafe(32)
        now = time.monotonic()
        with self._lock:
            self._by_token = {t: v for t, v in self._by_token.items() if v[1] > now}
            self._by_token[token] = (name, now + self.lifetime_s)
        return token

    def name(self, token: str | None) -> str:
        with self._lock:
            entry = self._by_token.get(token or "")
        now = time.monotonic()
        if token is None or entry is None or entry[1] < now:
            raise AuthError("not logged in to the register service (no token, or it "
                            "expired): authenticate again")
        with self._lock:
            self._by_token[token] = (entry[0], now + self.lifetime_s)
        return entry[0]

    def end(self, token: str | None) -> None:
        with self._lock:
            if token is not None:
                self._by_token.pop(token, None)


def create_app(reg: Register, tokens: Tokens | None = None,
               signing: Signing | None = None) -> Flask:
    """The service's WSGI application over one register (opened with the service role);
    with `signing`, the one holder of the lab's DCC signing key."""
    app = Flask("ratebench-register")
    ops = _Operations(reg, tokens or Tokens(), signing).table()

    def reply(data: bytes, status: int = 200) -> Response:
        return Response(data, status, mimetype="application/json")

    @app.get("/v1/info")
    def info() -> Response:
        return reply(wire.answer(wire.Info("ratebench register", sorted(ops),
                                           signing is not None)))

    @app.post("/v1/<op>")
    def call(op: str) -> Response:
        fn = ops.get(op)
        if fn is None:
            return reply(wire.refusal(f"no operation {op!r}", "register"), 404)
        from bench.app.station.settings import is_loopback

        if op in PASSWORD_OPS and request.scheme != "https" \
                and not is_loopback(request.remote_addr):
            return reply(wire.refusal("passwords are accepted over plain HTTP only from this "
                                      "machine; reach the service through its TLS proxy",
                                      "auth"), 403)
        via = (request.headers.get(VIA_HEADER) or "unnamed client")[:120]
        reset = ACTING_VIA.set(f"{via} at {request.remote_addr}")
        try:
            return reply(wire.answer(fn(op, request.get_data())))
        except AuthError as e:
            return reply(wire.refusal(str(e), "auth"), 403)
        except wire.Malformed as e:
            return reply(wire.refusal(str(e), "register"), 400)
        except RegisterError as e:
            return reply(wire.refusal(str(e), "register"), 409)
        finally:
            ACTING_VIA.reset(reset)

    return app


Handler = Callable[[str, bytes], wire.Answer]


def _op(kind: type[B], fn: Callable[[B], wire.Answer]) -> Handler:
    """An operation: its body decoded as `kind`, then `fn` of it."""
    return lambda op, data: fn(wire.body(op, data, kind))


class _Operations:
    """The service's operations over one register: each takes its body's Struct (wire.py),
    acts in the name of the account its token is bound to (`actor`), and answers a value
    of the register's."""

    def __init__(self, reg: Register, tok: Tokens, signing: Signing | None) -> None:
        self.reg, self.tok, self.signing = reg, tok, signing

    def actor(self, body: wire.Body) -> Account:
        acct = self.reg.account(self.tok.name(body.token))
        if acct is None or not acct.active:
            raise AuthError("the logged-in account is no longer active")
        return acct

    def login(self, b: wire.Login) -> wire.Answer:
        acct = self.reg.authenticate(b.name, b.password, b.role)
        return wire.LoginAnswer(acct, self.tok.start(acct.name))

    def allocate(self, b: wire.Allocate) -> wire.Answer:
        acct = self.actor(b)
        if not acct.has("signatory"):
            raise AuthError(f"{acct.name} is not a signatory: only a signatory's issue "
                            "allocates a number")
        return self.reg.allocate(b.run_uid, b.prefix, acct.name)

    def issue(self, b: wire.Issue) -> wire.Answer:
        return self.reg.issue(b.number, b.revision, self.actor(b), b.digests,
                              b.reason or None, wire.detail(b.detail))

    def append(self, b: wire.Append) -> wire.Answer:
        if b.action not in CLIENT_ACTIONS:
            raise RegisterError(f"audit action {b.action!r}: a client adds only "
                                f"{', '.join(CLIENT_ACTIONS)}; the register writes the rest")
        return self.reg.append(self.actor(b).name, b.action, b.obj, wire.detail(b.detail))

    def update_equipment(self, b: wire.UpdateEquipment) -> wire.Answer:
        return self.reg.update_equipment(
            self.actor(b), b.serial, b.certificate, b.issuer, b.due, b.calibrated_on, b.found,
            b.found_error, b.found_error_u)

    def register_run(self, b: wire.RegisterRun) -> wire.Answer:
        """A bench registers its run at the start; no person signs this (a run without
        --operator has none): the entry records the bench and its address (via)."""
        return self.reg.register_run(b.uid, b.bench, b.performer, b.version, b.simulated,
                                     b.inputs, b.items)

    def run_session(self, b: wire.RunSession) -> wire.Answer:
        self.reg.run_session(b.uid, b.session, b.performer)
        return None

    def impact_assessed(self, b: wire.ImpactAssessed) -> wire.Answer:
        """A logged-in quality account's impact assessment (issue 58): its audit entry."""
        return self.reg.impact_assessed(self.actor(b), b.serial, wire.detail(b.detail))

    def sign_dcc(self, b: wire.SignDcc) -> wire.Answer:
        """Sign an issued DCC (XAdES) for a signatory logged in here; the register must
        designate this key's certificate (its setting, an admin's decision)."""
        import hashlib

        from lxml import etree

        from bench.app.dcc.output import dcc_bytes
        from bench.app.dcc.signing import sign_tree

        acct = self.actor(b)
        if not acct.has("signatory"):
            raise AuthError(f"{acct.name} is not a signatory")
        if self.signing is None:
            raise RegisterError("this register service holds no signing key")
        want = self.reg.setting(SIGNING_SETTING)
        have = hashlib.sha256(self.signing.certificate_file.read_bytes()).hexdigest()
        if want != have:
            raise RegisterError("the register does not designate this service's signing "
                                f"certificate ({SIGNING_SETTING})")
        parser = etree.XMLParser(huge_tree=True, no_network=True, resolve_entities=False)
        tree = etree.ElementTree(etree.fromstring(b.xml, parser))
        data = dcc_bytes(sign_tree(tree, self.signing), pretty=False)   # as signed, not re-laid
        self.reg.append(acct.name, "DCC signed", acct.name,
                        {"sha256": hashlib.sha256(data).hexdigest()})
        return data

    def table(self) -> dict[str, Handler]:
        """The operations by name, as `POST /v1/<operation>` calls them."""
        return {**self._accounts(), **self._equipment(), **self._issues(), **self._runs()}

    def _accounts(self) -> dict[str, Handler]:
        reg, tok, actor = self.reg, self.tok, self.actor

        def logout(b: wire.Body) -> None:
            tok.end(b.token)

        return {
            "authenticate": _op(wire.Login, self.login),
            "logout": _op(wire.Body, logout),
            "change_password": _op(wire.ChangePassword, lambda b: reg.change_password(
                b.name, b.old, b.new)),
            "account": _op(wire.Named, lambda b: reg.account(b.name)),
            "accounts": _op(wire.Body, lambda b: reg.accounts()),
            "add_account": _op(wire.AddAccount, lambda b: reg.add_account(
                actor(b), b.name, b.full_name, b.roles, b.password, b.function or None)),
            "reset_password": _op(wire.ResetPassword, lambda b: reg.reset_password(
                actor(b), b.name, b.password)),
            "set_active": _op(wire.SetActive, lambda b: reg.set_active(actor(b), b.name,
                                                                      b.active)),
            "set_role": _op(wire.SetRole, lambda b: reg.set_role(actor(b), b.name, b.role,
                                                                b.grant)),
            "setting": _op(wire.Key, lambda b: reg.setting(b.key)),
            "settings": _op(wire.Body, lambda b: {k: reg.int_setting(k)
                                                  for k in SETTING_DEFAULTS}),
            "set_setting": _op(wire.SetSetting, lambda b: reg.set_setting(actor(b), b.key,
                                                                         b.value)),
        }

    def _equipment(self) -> dict[str, Handler]:
        reg, actor = self.reg, self.actor
        return {
            "equipment": _op(wire.EquipmentQuery, lambda b: reg.equipment(b.serial)),
            "add_equipment": _op(wire.AddEquipment, lambda b: reg.add_equipment(
                actor(b), b.serial, b.model, b.certificate, b.issuer, b.due, b.identity_only,
                b.calibrated_on)),
            "update_equipment": _op(wire.UpdateEquipment, self.update_equipment),
            "revoke_deviation": _op(wire.Serial, lambda b: reg.revoke_deviation(actor(b),
                                                                               b.serial)),
            "add_deviation": _op(wire.AddDeviation, lambda b: reg.add_deviation(
                actor(b), b.serial, b.reason, b.expires)),
            "runs_using": _op(wire.Serial, lambda b: reg.runs_using(b.serial)),
            "impact_assessed": _op(wire.ImpactAssessed, self.impact_assessed),
        }

    def _issues(self) -> dict[str, Handler]:
        reg, actor = self.reg, self.actor
        return {
            "withdraw": _op(wire.Withdraw, lambda b: reg.withdraw(actor(b), b.number,
                                                                 b.reason)),
            "allocate": _op(wire.Allocate, self.allocate),
            "number_of_run": _op(wire.RunUid, lambda b: reg.number_of_run(b.run_uid)),
            "revisions": _op(wire.Number, lambda b: reg.revisions(b.number)),
            "find_revision": _op(wire.Digest, lambda b: reg.find_revision(b.sha256)),
            "begin_issue": _op(wire.BeginIssue, lambda b: reg.begin_issue(
                actor(b), b.number, b.revision, b.result_sha256)),
            "issue": _op(wire.Issue, self.issue),
            "append": _op(wire.Append, self.append),
            "audit_rows": _op(wire.Body, lambda b: reg.audit_rows()),
            "audit_check": _op(wire.Body, lambda b: reg.audit_check()),
            "sign_dcc": _op(wire.SignDcc, self.sign_dcc),
        }

    def _runs(self) -> dict[str, Handler]:
        reg = self.reg
        return {
            "register_run": _op(wire.RegisterRun, self.register_run),
            "run_session": _op(wire.RunSession, self.run_session),
            "deliver_result": _op(wire.DeliverResult, lambda b: reg.deliver_result(
                b.uid, b.kind, b.result, b.raw, b.reason)),
            "run_record": _op(wire.Uid, lambda b: reg.run_record(b.uid)),
        }
