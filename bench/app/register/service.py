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

import dataclasses
import datetime as dt
import secrets
import threading
import time
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING

from flask import Flask, jsonify, request
from werkzeug.wrappers import Response

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
    from drivers.json_types import JsonValue

TOKEN_S = 15 * 60.0         # a login is good this long after its last use (a station's idle)
#: audit entries a bench or station may add in an authenticated person's name
CLIENT_ACTIONS = ("run started by", "control review", "station login", "station logout",
                  "station session ended", "station sign refused")
PASSWORD_OPS = ("authenticate", "change_password", "add_account", "reset_password")


def jsonable(value: object) -> JsonValue:
    """Dataclasses, dates and tuples as JSON (the client rebuilds them: client.py)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dt.date):
        return value.isoformat()
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if value is None or isinstance(value, str | int | float | bool):
        return value
    raise TypeError(f"{type(value).__name__} is not part of the register's protocol")


def _texts(value: object) -> list[str]:
    return [str(v) for v in value] if isinstance(value, list) else []


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

    def name(self, token: object) -> str:
        with self._lock:
            entry = self._by_token.get(token) if isinstance(token, str) else None
        now = time.monotonic()
        if entry is None or entry[1] < now:
            raise AuthError("not logged in to the register service (no token, or it "
                            "expired): authenticate again")
        with self._lock:
            self._by_token[str(token)] = (entry[0], now + self.lifetime_s)
        return entry[0]

    def end(self, token: object) -> None:
        with self._lock:
            if isinstance(token, str):
                self._by_token.pop(token, None)


def create_app(reg: Register, tokens: Tokens | None = None,
               signing: Signing | None = None) -> Flask:
    """The service's WSGI application over one register (opened with the service role);
    with `signing`, the one holder of the lab's DCC signing key."""
    app = Flask("ratebench-register")
    ops = _Operations(reg, tokens or Tokens(), signing).table()

    @app.get("/v1/info")
    def info() -> Response:
        return jsonify({"ok": {"service": "ratebench register", "operations": sorted(ops),
                               "signs_dcc": signing is not None}})

    @app.post("/v1/<op>")
    def call(op: str) -> tuple[Response, int]:
        fn = ops.get(op)
        if fn is None:
            return jsonify({"error": f"no operation {op!r}", "kind": "register"}), 404
        from bench.app.station.settings import is_loopback

        if op in PASSWORD_OPS and request.scheme != "https" \
                and not is_loopback(request.remote_addr):
            return jsonify({"error": "passwords are accepted over plain HTTP only from this "
                            "machine; reach the service through its TLS proxy",
                            "kind": "auth"}), 403
        body = request.get_json(silent=True)
        if not isinstance(body, dict):
            return jsonify({"error": "a JSON object expected", "kind": "register"}), 400
        via = (request.headers.get(VIA_HEADER) or "unnamed client")[:120]
        reset = ACTING_VIA.set(f"{via} at {request.remote_addr}")
        try:
            return jsonify({"ok": fn(body)}), 200
        except AuthError as e:
            return jsonify({"error": str(e), "kind": "auth"}), 403
        except RegisterError as e:
            return jsonify({"error": str(e), "kind": "register"}), 409
        finally:
            ACTING_VIA.reset(reset)

    return app


def _text(body: Mapping[str, object], key: str, optional: bool = False) -> str:
    value = body.get(key)
    if value is None and optional:
        return ""
    if not isinstance(value, str):
        raise RegisterError(f"{key}: text expected")
    return value


def _date(b: Mapping[str, object], key: str) -> dt.date:
    try:
        return dt.date.fromisoformat(_text(b, key))
    except ValueError:
        raise RegisterError(f"{key}: YYYY-MM-DD expected") from None


def _maybe_date(b: Mapping[str, object], key: str) -> dt.date | None:
    return None if b.get(key) is None else _date(b, key)


def _maybe_text(b: Mapping[str, object], key: str) -> str | None:
    return None if b.get(key) is None else _text(b, key)


def _number(b: Mapping[str, object], key: str) -> float | None:
    v = b.get(key)
    if v is not None and not isinstance(v, int | float):
        raise RegisterError(f"{key}: a number expected")
    return None if v is None else float(v)


def _strings(b: Mapping[str, object], key: str) -> dict[str, str]:
    v = b.get(key)
    if not isinstance(v, dict):
        raise RegisterError(f"{key}: an object expected")
    return {str(k): str(x) for k, x in v.items()}


class _Operations:
    """The service's operations over one register: each reads its JSON body, acts in the
    name of the account its token is bound to (`actor`), and answers a JSON value."""

    def __init__(self, reg: Register, tok: Tokens, signing: Signing | None) -> None:
        self.reg, self.tok, self.signing = reg, tok, signing

    def actor(self, body: Mapping[str, object]) -> Account:
        acct = self.reg.account(self.tok.name(body.get("token")))
        if acct is None or not acct.active:
            raise AuthError("the logged-in account is no longer active")
        return acct

    def login(self, b: Mapping[str, object]) -> JsonValue:
        role = b.get("role")
        acct = self.reg.authenticate(_text(b, "name"), _text(b, "password"),
                                     role if isinstance(role, str) else None)
        return {"account": jsonable(acct), "token": self.tok.start(acct.name)}

    def allocate(self, b: Mapping[str, object]) -> JsonValue:
        acct = self.actor(b)
        if not acct.has("signatory"):
            raise AuthError(f"{acct.name} is not a signatory: only a signatory's issue "
                            "allocates a number")
        return self.reg.allocate(_text(b, "run_uid"), _text(b, "prefix"), acct.name)

    def begin_issue(self, b: Mapping[str, object]) -> JsonValue:
        revision = b.get("revision")
        return jsonable(self.reg.begin_issue(self.actor(b), _text(b, "number"),
                                             revision if isinstance(revision, int) else 0,
                                             _text(b, "result_sha256", optional=True)))

    def issue(self, b: Mapping[str, object]) -> JsonValue:
        digests, detail, revision = b.get("digests"), b.get("detail"), b.get("revision")
        if not isinstance(digests, dict) or not isinstance(detail, dict) \
                or not isinstance(revision, int):
            raise RegisterError("issue: digests and detail objects, revision a number")
        return jsonable(self.reg.issue(_text(b, "number"), revision, self.actor(b),
                                       {str(k): str(v) for k, v in digests.items()},
                                       _text(b, "reason", optional=True) or None, detail))

    def append(self, b: Mapping[str, object]) -> JsonValue:
        action = _text(b, "action")
        if action not in CLIENT_ACTIONS:
            raise RegisterError(f"audit action {action!r}: a client adds only "
                                f"{', '.join(CLIENT_ACTIONS)}; the register writes the rest")
        detail = b.get("detail")
        return self.reg.append(self.actor(b).name, action, _text(b, "object"),
                               detail if isinstance(detail, dict) else {})

    def equipment(self, b: Mapping[str, object]) -> JsonValue:
        serial = b.get("serial")
        return jsonable(self.reg.equipment(serial if isinstance(serial, str) else None))

    def update_equipment(self, b: Mapping[str, object]) -> JsonValue:
        return jsonable(self.reg.update_equipment(
            self.actor(b), _text(b, "serial"), _text(b, "certificate"), _text(b, "issuer"),
            _date(b, "due"), _maybe_date(b, "calibrated_on"), _maybe_text(b, "found"),
            _number(b, "found_error"), _number(b, "found_error_u")))

    def register_run(self, b: Mapping[str, object]) -> JsonValue:
        """A bench registers its run at the start; no person signs this (a run without
        --operator has none): the entry records the bench and its address (via)."""
        items = b.get("items")
        return jsonable(self.reg.register_run(
            _text(b, "uid"), _text(b, "bench"), _maybe_text(b, "performer"),
            _text(b, "version"), bool(b.get("simulated")), _strings(b, "inputs"),
            [dict(i) for i in items if isinstance(i, dict)] if isinstance(items, list)
            else []))

    def deliver_result(self, b: Mapping[str, object]) -> JsonValue:
        import base64

        return jsonable(self.reg.deliver_result(
            _text(b, "uid"), _text(b, "kind"), base64.b64decode(_text(b, "result")),
            _strings(b, "raw"), _maybe_text(b, "reason")))

    def run_session(self, b: Mapping[str, object]) -> JsonValue:
        session = b.get("session")
        self.reg.run_session(_text(b, "uid"), session if isinstance(session, int) else 0,
                             _maybe_text(b, "performer"))
        return None

    def impact_assessed(self, b: Mapping[str, object]) -> JsonValue:
        """A logged-in quality account's impact assessment (issue 58): its audit entry."""
        detail = b.get("detail")
        return self.reg.impact_assessed(self.actor(b), _text(b, "serial"),
                                        detail if isinstance(detail, dict) else {})

    def sign_dcc(self, b: Mapping[str, object]) -> JsonValue:
        """Sign an issued DCC (XAdES) for a signatory logged in here; the register must
        designate this key's certificate (its setting, an admin's decision)."""
        import base64
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
        tree = etree.ElementTree(etree.fromstring(base64.b64decode(_text(b, "xml")), parser))
        data = dcc_bytes(sign_tree(tree, self.signing), pretty=False)   # as signed, not re-laid
        self.reg.append(acct.name, "DCC signed", acct.name,
                        {"sha256": hashlib.sha256(data).hexdigest()})
        return base64.b64encode(data).decode("ascii")

    def table(self) -> dict[str, Callable[[Mapping[str, object]], JsonValue]]:
        """The operations by name, as `POST /v1/<operation>` calls them."""
        reg, tok, actor = self.reg, self.tok, self.actor
        return {
            "authenticate": self.login,
            "logout": lambda b: tok.end(b.get("token")),
            "change_password": lambda b: reg.change_password(
                _text(b, "name"), _text(b, "old"), _text(b, "new")),
            "account": lambda b: jsonable(reg.account(_text(b, "name"))),
            "accounts": lambda b: jsonable(reg.accounts()),
            "add_account": lambda b: jsonable(reg.add_account(
                actor(b), _text(b, "name"), _text(b, "full_name"),
                _texts(b.get("roles")), _text(b, "password"),
                _text(b, "function", optional=True) or None)),
            "reset_password": lambda b: reg.reset_password(actor(b), _text(b, "name"),
                                                           _text(b, "password")),
            "set_active": lambda b: jsonable(reg.set_active(actor(b), _text(b, "name"),
                                                            bool(b.get("active")))),
            "set_role": lambda b: jsonable(reg.set_role(
                actor(b), _text(b, "name"), _text(b, "role"), bool(b.get("grant")))),
            "setting": lambda b: reg.setting(_text(b, "key")),
            "settings": lambda b: {k: reg.int_setting(k) for k in SETTING_DEFAULTS},
            "set_setting": lambda b: reg.set_setting(actor(b), _text(b, "key"),
                                                     _text(b, "value")),
            "equipment": self.equipment,
            "add_equipment": lambda b: reg.add_equipment(
                actor(b), _text(b, "serial"), _text(b, "model"), _maybe_text(b, "certificate"),
                _maybe_text(b, "issuer"), _maybe_date(b, "due"), bool(b.get("identity_only")),
                _maybe_date(b, "calibrated_on")),
            "update_equipment": self.update_equipment,
            "revoke_deviation": lambda b: reg.revoke_deviation(actor(b), _text(b, "serial")),
            "withdraw": lambda b: jsonable(reg.withdraw(actor(b), _text(b, "number"),
                                                        _text(b, "reason"))),
            "add_deviation": lambda b: reg.add_deviation(
                actor(b), _text(b, "serial"), _text(b, "reason"), _date(b, "expires")),
            "allocate": self.allocate,
            "number_of_run": lambda b: reg.number_of_run(_text(b, "run_uid")),
            "revisions": lambda b: jsonable(reg.revisions(_text(b, "number"))),
            "find_revision": lambda b: jsonable(reg.find_revision(_text(b, "sha256"))),
            "begin_issue": self.begin_issue,
            "issue": self.issue,
            "append": self.append,
            "audit_rows": lambda b: jsonable(reg.audit_rows()),
            "audit_check": lambda b: jsonable(reg.audit_check()),
            "sign_dcc": self.sign_dcc,
            "register_run": self.register_run,
            "run_session": self.run_session,
            "deliver_result": self.deliver_result,
            "run_record": lambda b: jsonable(reg.run_record(_text(b, "uid"))),
            "runs_using": lambda b: jsonable(reg.runs_using(_text(b, "serial"))),
            "impact_assessed": self.impact_assessed,
        }
