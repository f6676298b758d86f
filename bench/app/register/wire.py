"""The register's JSON, both ways (issue 60): the service's request bodies and answers
(service.py <-> client.py) and the JSON columns of its rows (store.py), as msgspec Structs
and the register's record dataclasses (model.py).

Why one module: every other module of the register reads attributes of typed values; a
body or a column that does not fit its type is refused here, naming the key path
(`add_account: $.roles[0]: expected text, got int`). Encoding a stored column keeps the
bytes of before (json.dumps, sorted keys where they were sorted): the audit trail's hash
chain covers them.
"""

from __future__ import annotations

import datetime as dt
import json
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Generic, TypeAlias, TypeVar, cast

import msgspec
from msgspec import Struct

from bench.app.register.chain import ChainReport
from bench.app.register.model import (
    Account,
    AuditDetail,
    AuditEntry,
    Calibration,
    Equipment,
    EventDetail,
    ItemRow,
    Receipt,
    RegisterError,
    Revision,
    RunEvent,
    RunRecord,
)
from drivers.json_types import JsonLike

T = TypeVar("T")
B = TypeVar("B", bound=Struct)


# -- request bodies: `POST /v1/<operation>` -------------------------------------------------

class Body(Struct, kw_only=True):
    """Every body may carry the token of a login (service.Tokens); an operation in a
    person's name refuses one without it (AuthError, not a malformed body)."""

    token: str | None = None


class Login(Body):
    name: str
    password: str
    role: str | None = None


class ChangePassword(Body):
    name: str
    old: str
    new: str


class Named(Body):
    name: str


class AddAccount(Body):
    name: str
    full_name: str
    password: str
    roles: list[str] = []
    function: str | None = None


class ResetPassword(Body):
    name: str
    password: str


class SetActive(Body):
    name: str
    active: bool = False


class SetRole(Body):
    name: str
    role: str
    grant: bool = False


class Key(Body):
    key: str


class SetSetting(Body):
    key: str
    value: str


class Serial(Body):
    serial: str


class EquipmentQuery(Body):
    serial: str | None = None


class AddEquipment(Body):
    serial: str
    model: str
    certificate: str | None = None
    issuer: str | None = None
    due: dt.date | None = None
    identity_only: bool = False
    calibrated_on: dt.date | None = None


class UpdateEquipment(Body):
    serial: str
    certificate: str
    issuer: str
    due: dt.date
    calibrated_on: dt.date | None = None
    found: str | None = None
    found_error: float | None = None
    found_error_u: float | None = None


class Withdraw(Body):
    number: str
    reason: str


class AddDeviation(Body):
    serial: str
    reason: str
    expires: dt.date


class Allocate(Body):
    run_uid: str
    prefix: str


class RunUid(Body):
    run_uid: str


class Number(Body):
    number: str


class Digest(Body):
    sha256: str


class BeginIssue(Body):
    number: str
    revision: int = 0
    result_sha256: str = ""


class Issue(Body):
    number: str
    revision: int
    digests: dict[str, str]
    detail: Mapping[str, object]
    reason: str | None = None


class Append(Body):
    action: str
    obj: str = msgspec.field(name="object")
    detail: Mapping[str, object] = {}


class SignDcc(Body):
    xml: bytes          # base64 on the wire


class RegisterRun(Body):
    uid: str
    bench: str
    version: str
    inputs: dict[str, str]
    performer: str | None = None
    simulated: bool = False
    items: list[dict[str, str | None]] = []


class RunSession(Body):
    uid: str
    session: int = 0
    performer: str | None = None


class DeliverResult(Body):
    uid: str
    kind: str
    result: bytes       # result.json's bytes, base64 on the wire
    raw: dict[str, str]
    reason: str | None = None


class Uid(Body):
    uid: str


class ImpactAssessed(Body):
    serial: str
    detail: Mapping[str, object] = {}


#: the register service's own answers besides the register's records
class LoginAnswer(Struct):
    account: Account
    token: str


class Info(Struct):
    service: str
    operations: list[str]
    signs_dcc: bool = False


class Ok(Struct, Generic[T]):
    ok: T


class Refusal(Struct):
    error: str
    kind: str = "register"


#: what an operation answers (encoded by `answer`)
Answer: TypeAlias = (Account | list[Account] | Equipment | list[Equipment] | Calibration
                     | Revision | list[Revision] | Receipt | RunRecord | list[RunRecord]
                     | list[AuditEntry] | ChainReport | LoginAnswer | Info | dict[str, int]
                     | bytes | str | int | None)


class Malformed(RegisterError):
    """A request's body that is not its operation's (the service answers 400)."""


_AT = re.compile(r" - at `\$(?P<path>[^`]*)`$")


def _message(e: msgspec.MsgspecError) -> str:
    """msgspec's message with the key path first, as the register's other refusals."""
    text = str(e)
    m = _AT.search(text)
    return f"${m['path']}: {text[:m.start()]}" if m else text


def body(op: str, data: bytes, kind: type[B]) -> B:
    """A request's body as its operation's Struct (RegisterError naming the key)."""
    try:
        return msgspec.json.decode(data or b"{}", type=kind)
    except (msgspec.ValidationError, msgspec.DecodeError) as e:
        raise Malformed(f"{op}: {_message(e)}") from None


def request(value: Body) -> bytes:
    """A request's body as the client sends it."""
    return msgspec.json.encode(value)


def answer(value: Answer) -> bytes:
    """An operation's answer, `{"ok": value}`."""
    return msgspec.json.encode(Ok(value))


def refusal(text: str, kind: str) -> bytes:
    """A refused request's answer, `{"error": text, "kind": kind}`."""
    return msgspec.json.encode(Refusal(text, kind))


def answered(op: str, data: bytes, want: type[T]) -> T:
    """The value of the service's answer to `op`, as `want` (RegisterError: the answer is
    not one)."""
    try:
        return msgspec.json.decode(data, type=Ok[want]).ok  # type: ignore[valid-type]
    except (msgspec.ValidationError, msgspec.DecodeError) as e:
        raise RegisterError(f"the register service's answer to {op}: {_message(e)}") \
            from None


def answered_or_none(op: str, data: bytes, want: type[T]) -> T | None:
    """As `answered`, where the service may answer null (none such)."""
    return answered(op, data, want | None)  # type: ignore[arg-type]


def refused(data: bytes) -> Refusal | None:
    """The service's refusal in an error response (None: not one, e.g. a proxy's page)."""
    try:
        return msgspec.json.decode(data, type=Refusal)
    except (msgspec.ValidationError, msgspec.DecodeError):
        return None


def builtins(value: object) -> JsonLike:
    """A value for an audit detail as JSON's values (TypeError: it holds something else)."""
    return cast(JsonLike, msgspec.to_builtins(value))


def detail(value: Mapping[str, object]) -> AuditDetail:
    """An audit detail as decoded from a body: JSON's values only (msgspec decoded it)."""
    return cast(AuditDetail, value)


# -- the register's JSON columns -------------------------------------------------------------

def dump_sorted(value: Mapping[str, str] | Sequence[ItemRow]) -> str:
    """A run's inputs, raw digests or items as stored: keys sorted (as since g0004)."""
    return json.dumps(value, sort_keys=True)


def dump_event(value: AuditDetail) -> str:
    """A run event's detail as stored: its keys in the order written."""
    return json.dumps(value)


def digests(text: str, column: str) -> dict[str, str]:
    """A run's inputs or raw captures column (name -> SHA-256)."""
    return _column(text, dict[str, str], column)


def items(text: str) -> tuple[dict[str, str | None], ...]:
    """A run's items column: each stand item's status at the start."""
    return _column(text, tuple[dict[str, str | None], ...], "items")


def event(utc: str, kind: str, text: str) -> RunEvent:
    """A run event as stored (its detail one JSON object)."""
    return RunEvent(utc, kind, _column(text, EventDetail, "event detail"))


def _column(text: str, kind: type[T], what: str) -> T:
    try:
        return msgspec.json.decode(text, type=kind)
    except (msgspec.ValidationError, msgspec.DecodeError) as e:
        raise RegisterError(f"register: a run's {what} as stored: {_message(e)}") from None


# -- what the register's checks read of a run folder -----------------------------------------

class PerformerRecord(Struct):
    """meta.json's performer: the account the register authenticated at the start
    (gate.authenticate_performer)."""

    account: str | None = None
    full_name: str | None = None
    function: str | None = None
    register: str | None = None
    authenticated_utc: str | None = None


class RunStart(Struct):
    """meta.json's facts of the run's start that the register's record is held against."""

    run_uid: str | None = None
    bench_version: str | None = None
    performer: PerformerRecord | None = None
    equipment_register: str | None = None
    equipment_status: list[dict[str, str | None]] | None = None
    os_user: str | None = None
    operator: str | None = None


class StandFacts(Struct):
    simulated: bool = False


class ResultFacts(Struct):
    """What the register's checks read of a result.json: the stand's kind and the
    corrections the analysis applied (compared as JSON values, never read further)."""

    stand: StandFacts | None = None
    corrections: object = None


def run_start(path: Path) -> RunStart:
    """A run folder's meta.json (RegisterError naming the file and the key)."""
    return _file(path, RunStart)


def result_facts(data: str | bytes | None) -> ResultFacts:
    """A registered result's facts; a result that does not state them states none."""
    try:
        return msgspec.json.decode(data or b"{}", type=ResultFacts)
    except (msgspec.ValidationError, msgspec.DecodeError):
        return ResultFacts()


def corrections_file(path: Path) -> ResultFacts:
    """The run folder's corrections file (its `corrections`; RegisterError: unreadable)."""
    return _file(path, ResultFacts)


def _file(path: Path, kind: type[T]) -> T:
    try:
        return msgspec.json.decode(path.read_bytes(), type=kind)
    except OSError as e:
        raise RegisterError(f"{path}: cannot be read: {e}") from None
    except (msgspec.ValidationError, msgspec.DecodeError) as e:
        raise RegisterError(f"{path}: cannot be read: {_message(e)}") from None
