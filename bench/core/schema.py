"""Schemas for the bench's YAML files, declared as data.

A schema node checks one value and reports every problem it finds (not just the
first) as a `Problem` naming file, line and key path. Unknown keys are refused: a
misspelt `turnz: 50` must not silently fall back to a default on a day-long run.

A setting is declared once, as a field of a msgspec Struct (the stand's instruments in
drivers/, the twins' truth in sims/truth.py, the stand file, the lab file and
each procedure kind's keys): the field's type, default, bounds (`Meta(ge=..)`), unit
(`Meta(extra={"unit": ..})`) and meaning (`Meta(description=..)`). `struct_map` derives
the file's schema from the Struct (so `bench validate`, `bench schema` and the JSON Schema
read the same declaration) and `struct_at` builds the object with msgspec, placing what
msgspec or a rule of the Struct refuses (its `$.a.b` path) at the file's line and key.
The check is this module's nodes: they report every problem of a file (msgspec stops at
the first) at its file, line and key, with the messages the tests and the operators know.
"""

from __future__ import annotations

import datetime as dt
import functools
import math
import re
import types
import typing
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, TypeVar

import msgspec

from bench.core.yamlfile import KeyPath, Problem, YamlDoc
from drivers.calibration import parse_date as parse_date

#: a JSON Schema document (or a part of one), as `json.dumps` writes it
JsonSchema = dict[str, object]


class Node:
    """A schema for one value.

    The same node checks a file (`check`), describes itself in the reference
    (`description`, `unit_text`) and states itself as JSON Schema (`json_schema`), so
    `bench schema`, docs/configuration.md and `bench validate` cannot disagree.
    """

    description = "a value"
    unit_text = ""

    def check(self, value: object, path: KeyPath, doc: YamlDoc, out: list[Problem]) -> None:
        raise NotImplementedError

    def json_schema(self) -> JsonSchema:
        """This node as JSON Schema (draft 2020-12) of the file's data."""
        return {}


def _type_name(value: object) -> str:
    if value is None:
        return "nothing"
    return {bool: "true/false", int: "an integer", float: "a number", str: "text",
            list: "a list", dict: "a mapping"}.get(type(value), type(value).__name__)


def _finite(value: int | float) -> bool:
    """Finite and usable as a float (an integer of 400 digits is not)."""
    try:
        return math.isfinite(value) and abs(float(value)) < 1e300
    except OverflowError:
        return False


@dataclass(frozen=True)
class Num(Node):
    """A real number (int or float) within optional bounds."""

    min: float | None = None
    max: float | None = None
    exclusive_min: bool = False
    integer: bool = False
    unit: str = ""

    @property
    def description(self) -> str:  # type: ignore[override]
        kind = "an integer" if self.integer else "a number"
        bits = []
        if self.min is not None:
            bits.append(f"{'>' if self.exclusive_min else '>='} {self.min:g}")
        if self.max is not None:
            bits.append(f"<= {self.max:g}")
        unit = f" {self.unit}" if self.unit else ""
        return kind + (f" {' and '.join(bits)}" if bits else "") + unit

    @property
    def unit_text(self) -> str:  # type: ignore[override]
        return self.unit

    def json_schema(self) -> JsonSchema:
        out: JsonSchema = {"type": "integer" if self.integer else "number"}
        if self.min is not None:
            out["exclusiveMinimum" if self.exclusive_min else "minimum"] = self.min
        if self.max is not None:
            out["maximum"] = self.max
        if self.unit:
            out["x-unit"] = self.unit
        return out

    def check(self, value: object, path: KeyPath, doc: YamlDoc, out: list[Problem]) -> None:
        if isinstance(value, bool) or not isinstance(value, int | float) \
                or (self.integer and not isinstance(value, int)) or not _finite(value):
            out.append(doc.problem(path, f"expected {self.description}, got {_type_name(value)}"
                                         f" {value!r}"))
            return
        low_bad = self.min is not None and (value <= self.min if self.exclusive_min
                                            else value < self.min)
        if low_bad or (self.max is not None and value > self.max):
            out.append(doc.problem(path, f"expected {self.description}, got {value!r}"))


@dataclass(frozen=True)
class Str(Node):
    choices: tuple[str, ...] = ()

    @property
    def description(self) -> str:  # type: ignore[override]
        return f"one of {', '.join(self.choices)}" if self.choices else "text"

    def check(self, value: object, path: KeyPath, doc: YamlDoc, out: list[Problem]) -> None:
        if not isinstance(value, str):
            out.append(doc.problem(path, f"expected {self.description}, got "
                                         f"{_type_name(value)} {value!r}"))
        elif self.choices and value not in self.choices:
            out.append(doc.problem(path, f"expected {self.description}, got {value!r}"))

    def json_schema(self) -> JsonSchema:
        return {"type": "string", **({"enum": list(self.choices)} if self.choices else {})}


@dataclass(frozen=True)
class Date(Node):
    """A calendar date, YYYY-MM-DD (YAML may already have made it a date)."""

    description = "a date YYYY-MM-DD"

    def check(self, value: object, path: KeyPath, doc: YamlDoc, out: list[Problem]) -> None:
        if parse_date(value) is None:
            out.append(doc.problem(path, f"expected {self.description}, got {value!r}"))

    def json_schema(self) -> JsonSchema:
        return {"type": "string", "format": "date"}


@dataclass(frozen=True)
class Bool(Node):
    description = "true or false"

    def check(self, value: object, path: KeyPath, doc: YamlDoc, out: list[Problem]) -> None:
        if not isinstance(value, bool):
            out.append(doc.problem(path, f"expected true or false, got {value!r}"))

    def json_schema(self) -> JsonSchema:
        return {"type": "boolean"}


@dataclass(frozen=True)
class Any_(Node):
    description = "anything"

    def check(self, value: object, path: KeyPath, doc: YamlDoc, out: list[Problem]) -> None:
        return


@dataclass(frozen=True)
class OneOf(Node):
    """A value any one of several schemas accepts (e.g. a number, or the word max)."""

    options: tuple[Node, ...]

    def __init__(self, *options: Node) -> None:
        object.__setattr__(self, "options", options)

    @property
    def description(self) -> str:  # type: ignore[override]
        return " or ".join(o.description for o in self.options)

    def check(self, value: object, path: KeyPath, doc: YamlDoc, out: list[Problem]) -> None:
        for o in self.options:
            found: list[Problem] = []
            o.check(value, path, doc, found)
            if not found:
                return
        out.append(doc.problem(path, f"expected {self.description}, got "
                                     f"{_type_name(value)} {value!r}"))

    @property
    def unit_text(self) -> str:  # type: ignore[override]
        return next((o.unit_text for o in self.options if o.unit_text), "")

    def json_schema(self) -> JsonSchema:
        return {"anyOf": [o.json_schema() for o in self.options]}


@dataclass(frozen=True)
class ListOf(Node):
    item: Node
    min_len: int = 0

    @property
    def description(self) -> str:  # type: ignore[override]
        return f"a list of {self.item.description}"

    def check(self, value: object, path: KeyPath, doc: YamlDoc, out: list[Problem]) -> None:
        if not isinstance(value, list):
            out.append(doc.problem(path, f"expected {self.description}, got "
                                         f"{_type_name(value)} {value!r}"))
            return
        if len(value) < self.min_len:
            out.append(doc.problem(path, f"expected at least {self.min_len} item(s)"))
        for i, v in enumerate(value):
            self.item.check(v, (*path, i), doc, out)

    @property
    def unit_text(self) -> str:  # type: ignore[override]
        return self.item.unit_text

    def json_schema(self) -> JsonSchema:
        out: JsonSchema = {"type": "array", "items": self.item.json_schema()}
        return {**out, "minItems": self.min_len} if self.min_len else out


@dataclass(frozen=True)
class Key:
    """A key of a mapping: its schema, whether it must be written, what it means, and
    its default when omitted (None: no default; the reference says what happens)."""

    node: Node
    required: bool = False
    doc: str = ""
    default: object = None


@dataclass(frozen=True)
class Map(Node):
    """A mapping with known keys; anything else is refused by name."""

    keys: Mapping[str, Key] = field(default_factory=dict)
    description = "a mapping"

    def check(self, value: object, path: KeyPath, doc: YamlDoc, out: list[Problem]) -> None:
        if not isinstance(value, dict):
            out.append(doc.problem(path, f"expected a mapping with keys "
                                         f"{', '.join(self.keys)}, got {_type_name(value)}"))
            return
        for k, v in value.items():
            spec = self.keys.get(k)
            if spec is None:
                out.append(doc.problem((*path, k), f"unknown key; allowed here: "
                                                   f"{', '.join(self.keys)}"))
            else:
                spec.node.check(v, (*path, k), doc, out)
        for k, spec in self.keys.items():
            if spec.required and k not in value:
                out.append(doc.problem(path, f"missing required key {k!r} "
                                             f"({spec.node.description})"))

    def json_schema(self) -> JsonSchema:
        props: JsonSchema = {}
        for k, spec in self.keys.items():
            s = spec.node.json_schema()
            if spec.doc:
                s = {**s, "description": spec.doc}
            if spec.default is not None:
                s = {**s, "default": spec.default}
            props[k] = s
        out: JsonSchema = {"type": "object", "properties": props,
                               "additionalProperties": False}
        required = [k for k, spec in self.keys.items() if spec.required]
        return {**out, "required": required} if required else out


@dataclass(frozen=True)
class MapOf(Node):
    """A mapping from names the user chooses (axis names) to values of one schema."""

    value: Node
    min_len: int = 0

    @property
    def description(self) -> str:  # type: ignore[override]
        return f"a mapping of names to {self.value.description}"

    def check(self, value: object, path: KeyPath, doc: YamlDoc, out: list[Problem]) -> None:
        if not isinstance(value, dict):
            out.append(doc.problem(path, f"expected {self.description}, got "
                                         f"{_type_name(value)}"))
            return
        if len(value) < self.min_len:
            out.append(doc.problem(path, f"expected at least {self.min_len} entry"))
        for k, v in value.items():
            self.value.check(v, (*path, str(k)), doc, out)

    def json_schema(self) -> JsonSchema:
        out: JsonSchema = {"type": "object", "additionalProperties": self.value.json_schema()}
        return {**out, "minProperties": self.min_len} if self.min_len else out


@dataclass(frozen=True)
class Check(Node):
    """A schema plus a rule that needs the whole value (e.g. min < max).

    The rule returns None, a message about the whole value, or (path inside the value,
    message) pairs, so each problem is reported at the line of the key that causes it.
    """

    inner: Node
    #: called with a value `inner` accepted (so of the type `inner` checks)
    rule: Callable[[Any], str | None | list[tuple[KeyPath, str]]]

    @property
    def description(self) -> str:  # type: ignore[override]
        return self.inner.description

    @property
    def unit_text(self) -> str:  # type: ignore[override]
        return self.inner.unit_text

    def json_schema(self) -> JsonSchema:
        """The inner schema: the rule needs the whole value and stays `bench validate`'s."""
        return self.inner.json_schema()

    def check(self, value: object, path: KeyPath, doc: YamlDoc, out: list[Problem]) -> None:
        before = len(out)
        self.inner.check(value, path, doc, out)
        if len(out) == before:
            found = self.rule(value)
            for sub, msg in [((), found)] if isinstance(found, str) else found or []:
                out.append(doc.problem((*path, *sub), msg))


def validate(doc: YamlDoc, schema: Node) -> list[Problem]:
    out: list[Problem] = []
    schema.check(doc.data, (), doc, out)
    return out


def merge(a: Node, b: Node) -> Node:
    """One schema accepting what either accepts, key by key (the stand file every
    procedure kind reads): a key is required only where both require it."""
    if a == b:
        return a
    if isinstance(a, Map) and isinstance(b, Map):
        keys: dict[str, Key] = {}
        for k in (*a.keys, *(k for k in b.keys if k not in a.keys)):
            ka, kb = a.keys.get(k), b.keys.get(k)
            if ka is None or kb is None:
                only = ka or kb
                assert only is not None
                keys[k] = Key(only.node, False, only.doc, only.default)
            else:
                keys[k] = Key(merge(ka.node, kb.node), ka.required and kb.required,
                              ka.doc or kb.doc,
                              ka.default if ka.default is not None else kb.default)
        return Map(keys)
    if isinstance(a, MapOf) and isinstance(b, MapOf):
        return MapOf(merge(a.value, b.value), min(a.min_len, b.min_len))
    if isinstance(a, ListOf) and isinstance(b, ListOf):
        return ListOf(merge(a.item, b.item), min(a.min_len, b.min_len))
    if isinstance(a, Check) and isinstance(b, Check) and a.rule is b.rule:
        return Check(merge(a.inner, b.inner), a.rule)
    return OneOf(a, b)


# -- settings declared once, as msgspec Structs --------------------------------------------

S = TypeVar("S", bound=msgspec.Struct)


def _shown(default: object) -> object:
    """A default the reference prints (a nested object's are its own keys'; an empty
    list is "none", not a value to write)."""
    if isinstance(default, bool | int | float | str) or (isinstance(default, tuple | list)
                                                         and default):
        return default
    return None


def _metas(tp: object) -> tuple[object, list[msgspec.Meta]]:
    """A type without its `Annotated` layers, and their msgspec.Meta (outermost last)."""
    metas: list[msgspec.Meta] = []
    while typing.get_origin(tp) is typing.Annotated:
        metas[:0] = [m for m in tp.__metadata__ if isinstance(m, msgspec.Meta)]  # type: ignore[attr-defined]
        tp = tp.__origin__  # type: ignore[attr-defined]
    return tp, metas


def _meta(metas: list[msgspec.Meta], name: str) -> Any:
    """The last Meta's `name` that is set (a field's own Meta over its alias's)."""
    found = None
    for m in metas:
        if getattr(m, name) is not None:
            found = getattr(m, name)
    return found


def _struct_node(tp: object, metas: list[msgspec.Meta]) -> Node:
    """The schema node of a Struct field's type, its bounds and unit from its Meta, and
    a rule that needs the whole value (`Meta.extra["check"]`, as `Check`'s: its problems
    are reported with every other one, at their keys)."""
    tp, more = _metas(tp)
    node = _bare_node(tp, [*more, *metas])
    rule = (_meta(more, "extra") or {}).get("check")
    return Check(node, rule) if rule is not None else node


def _bare_node(tp: object, metas: list[msgspec.Meta]) -> Node:
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        options = [a for a in args if a is not type(None)]
        if len(options) == 1:
            return _struct_node(options[0], metas)
        return OneOf(*(_struct_node(a, metas) for a in options))
    if origin is typing.Literal:
        return Str(tuple(str(a) for a in args))
    if tp is str:   # a choice among names the code holds (`Meta.extra["choices"]`)
        return Str(tuple((_meta(metas, "extra") or {}).get("choices", ())))
    if tp is int or tp is float:
        gt, ge = _meta(metas, "gt"), _meta(metas, "ge")
        extra = _meta(metas, "extra") or {}
        return Num(min=gt if gt is not None else ge, max=_meta(metas, "le"),
                   exclusive_min=gt is not None, integer=tp is int,
                   unit=str(extra.get("unit", "")))
    if isinstance(tp, type) and issubclass(tp, msgspec.Struct):
        return struct_map(tp)
    if origin in (Mapping, dict) and len(args) == 2:
        return MapOf(_struct_node(args[1], []), _meta(metas, "min_length") or 0)
    if origin in (tuple, list) and args:
        return ListOf(_struct_node(args[0], []), _meta(metas, "min_length") or 0)
    plain: dict[object, Node] = {bool: Bool(), dt.date: Date()}
    return plain.get(tp, Any_())


@functools.cache
def struct_map(cls: type[msgspec.Struct]) -> Map:
    """The schema of a mapping whose keys are `cls`'s fields, in their order: each key's
    node, meaning (`Meta.description`), unit (`Meta.extra["unit"]`) and default read from
    the one declaration. `Meta.extra["given"]`:
    the loader gives the value when the file leaves the key out (no default shown);
    `Meta.extra["required"]`: a file must write the key, an object made in code need not;
    `Meta.extra["file"] = False`: not a key of this block (the file states it elsewhere);
    `Meta.extra["written"]`: the type the file writes the key as, where the object holds
    what the parse makes of it (the twins' truth from `sim.axes`, a block kept as written)."""
    keys: dict[str, Key] = {}
    for f in msgspec.structs.fields(cls):   # its types resolved, with their Annotated
        tp = f.type
        metas = _metas(tp)[1]
        if typing.get_origin(tp) in (typing.Union, types.UnionType):
            metas = [m for a in typing.get_args(tp) for m in _metas(a)[1]]
        extra = _meta(metas, "extra") or {}
        if extra.get("file") is False:   # set in code, stated elsewhere in the file
            continue
        given = bool(extra.get("given"))
        required = (f.required and not given) or bool(extra.get("required"))
        default = f.default if f.default is not msgspec.NODEFAULT else None
        written = extra.get("written")
        keys[f.encode_name] = Key(_struct_node(tp if written is None else written, []),
                                  required,
                                  _meta(metas, "description") or "",
                                  None if required or given else _shown(default))
    return Map(keys)


class SettingsRefused(ValueError):
    """A settings block msgspec refused, at the key path in its file of the key it names."""

    def __init__(self, path: KeyPath, message: str) -> None:
        super().__init__(message)
        self.path = path
        self.message = message


_AT = re.compile(r"(?P<message>.*?)(?: - at `\$(?P<path>[^`]*)`)?$", re.S)
_STEP = re.compile(r"\.([^.\[]+)|\[(\d+|\.\.\.)\]")


def _refused(e: msgspec.ValidationError, at: KeyPath,
             fields: tuple[str, ...]) -> SettingsRefused:
    """msgspec's message as a Problem's: its `$.a.b[0]` path after `at`, and a rule's
    message naming its key first ("watchdog_ms: ...") placed at that key."""
    m = _AT.match(str(e))
    assert m is not None   # the pattern matches any text
    message, path = m.group("message"), list(at)
    for name, index in _STEP.findall(m.group("path") or ""):
        if name:
            path.append(name)
        elif index != "...":   # a mapping's value: the mapping's key is the nearest line
            path.append(int(index))
    key, sep, rest = message.partition(": ")
    if sep and not m.group("path") and key in fields:
        path.append(key)
        message = rest
    unknown = re.fullmatch(r"Object contains unknown field `(.+)`", message)
    if unknown:   # the schema's nodes report this first; kept for a block checked alone
        path.append(unknown.group(1))
        message = "unknown key"
    return SettingsRefused(tuple(path), message)


def _text_keys(value: object) -> object:
    """A YAML value with its mappings' keys as text (`20: C` is the key "20"): the nodes
    accept any key and name it as text, so the object does too."""
    if isinstance(value, dict):
        return {str(k): _text_keys(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_text_keys(v) for v in value]
    return value


def struct_at(cls: type[S], data: Mapping[str, object], at: KeyPath = (),
              **given: object) -> S:
    """`cls` from a validated YAML mapping (`given` values win); SettingsRefused names
    the key path under `at` of what msgspec or a rule of `cls` refused."""
    try:
        return msgspec.convert({**{str(k): _text_keys(v) for k, v in data.items()},
                                **given}, cls)
    except msgspec.ValidationError as e:
        raise _refused(e, at, tuple(f.encode_name for f in msgspec.structs.fields(cls))) \
            from None
