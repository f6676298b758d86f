"""A typed result part (msgspec Structs) as the builtins result.json's writer takes (issue 60).

Why not msgspec's own JSON encoder: it writes floats in its own shortest form (1e-05 as
0.00001), and result.json's bytes are `json.dumps`' (the writer in bench/core/journal.py);
so a model is turned into builtins in its Structs' field order, and the writer writes them
as before.
"""

from __future__ import annotations

import re
from typing import cast

import msgspec

from drivers.json_types import JsonObject


def _builtin(value: object) -> object:
    """A numpy scalar as the Python number it holds (json.dumps writes both alike)."""
    item = getattr(value, "item", None)
    if callable(item):
        return item()
    raise NotImplementedError(f"{type(value).__name__} is no JSON value")


def _lists(value: object) -> object:
    """msgspec's builtins keep a tuple a tuple; JSON's arrays are lists (as `json.load`
    gives them back, so a reader of the document in memory sees what a reader of the file
    does)."""
    if isinstance(value, tuple | list):
        return [_lists(v) for v in value]
    if isinstance(value, dict):
        return {k: _lists(v) for k, v in value.items()}
    return value


def encode(model: msgspec.Struct) -> JsonObject:
    """A model part as result.json's writer takes it: builtins in the Structs' field order."""
    return cast(JsonObject, _lists(msgspec.to_builtins(model, enc_hook=_builtin)))


_AT = re.compile(r" - at `\$(?P<path>[^`]*)`$")
_MISSING = re.compile(r"^Object missing required field `(?P<key>[^`]+)`")
_EXPECTED = re.compile(r"^Expected `(?P<want>[^`]+)`, got `(?P<got>[^`]+)`")
#: msgspec's type names, as a reader of result.json says them
_TYPES = {"float": "a number", "int": "an integer", "bool": "true or false",
          "object": "an object", "array": "a list", "str": "text", "null": "null"}


def problem_of(err: msgspec.ValidationError) -> tuple[str, str]:
    """msgspec's refusal in result.json's words: (msgspec's key path below the node it
    decoded, `.axes[...].turns` or '' at the node itself; the problem), a missing key
    named at its own path (`.rates[0].set_rate_dps`, 'missing'). The kinds' codecs put
    their part's root (and a mapping's key, which msgspec does not name) before it."""
    text = str(err)
    at = _AT.search(text)
    path = at["path"] if at else ""
    text = text[:at.start()] if at else text
    if m := _MISSING.match(text):
        return f"{path}.{m['key']}", "missing"
    if m := _EXPECTED.match(text):
        want = " or ".join(_TYPES.get(t, t) for t in m["want"].split(" | "))
        return path, f"expected {want}, got {m['got']}"
    return path, text
