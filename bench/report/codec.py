"""A typed result part (msgspec Structs) as the builtins result.json's writer takes (issue 60).

Why not msgspec's own JSON encoder: it writes floats in its own shortest form (1e-05 as
0.00001), and result.json's bytes are `json.dumps`' (the writer in bench/core/journal.py);
so a model is turned into builtins in its Structs' field order, and the writer writes them
as before.
"""

from __future__ import annotations

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
