"""JSON as a type: what `json.loads` gives back and `json.dumps` takes, for the records a
driver, twin or the bench writes into result.json, events.jsonl and the raw journals, and
for documents only passed through (issue 45: no `Any` where the value is JSON).

It lives at the bottom layer (drivers/) so every layer may name it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TypeAlias

#: a JSON scalar
JsonScalar: TypeAlias = str | int | float | bool | None
#: any JSON value, as `json.loads` returns it
JsonValue: TypeAlias = JsonScalar | list["JsonValue"] | dict[str, "JsonValue"]
#: settings as an instrument read them back at connect, by name (journaled, and shown on
#: the certificate)
Readback: TypeAlias = Mapping[str, JsonScalar]
#: a JSON object, as `json.loads` returns it
JsonObject: TypeAlias = dict[str, JsonValue]
#: a value `json.dumps` can write (read-only containers: a `dict[str, float]` is one)
JsonLike: TypeAlias = JsonScalar | Sequence["JsonLike"] | Mapping[str, "JsonLike"]
