"""The run's settings blocks as result.json carries them, decoded into the core's types:
the instruments' identities (`instruments`) and the lab's keys in `certificate`.

result.json is read back by the certificate, the DCC and `bench authorise`; what is not
of the expected type is refused naming its key path in result.json's terms (a hand-edited
file), never read as something else.
"""

from __future__ import annotations

from collections.abc import Mapping

import msgspec

from bench.core.lab import LabError, LabKeys
from bench.core.traceability import Identities
from drivers.json_types import JsonObject


def _refused(block: str, e: msgspec.ValidationError) -> str:
    """msgspec's `... - at `$.x[0]`` as result.json's key path `block.x[0]`."""
    text = str(e)
    message, _, at = text.rpartition(" - at `$")
    return f"result.json: {block}{at.rstrip('`')}: {message}" if message else \
        f"result.json: {block}: {text}"


def identities(instruments: Mapping[str, JsonObject]) -> Identities:
    """result.json's `instruments` block: per axis, each role's identity text."""
    try:
        return msgspec.convert(dict(instruments), dict[str, dict[str, str]])
    except msgspec.ValidationError as e:
        raise ValueError(_refused("instruments", e)) from None


def lab_keys(certificate: JsonObject) -> LabKeys | None:
    """The lab's keys in result.json's `certificate` block (None: it names no laboratory,
    so the lab file copied into the run directory is the run's); the customer's keys
    beside them are not the lab's."""
    if not certificate.get("laboratory"):
        return None
    try:
        return msgspec.convert(certificate, LabKeys)
    except msgspec.ValidationError as e:
        raise LabError(_refused("certificate", e)) from None
