"""Metrological traceability as the stand file states it (ISO/IEC 17025 6.5, 7.8.4.1 c).

Every instrument of the stand may carry `calibration: {certificate, issuer, due, traces}`,
and `traceability:` lists the references and sensors the bench does not drive (a 10 MHz
reference, the zero-mark sensor, a shunt). This module walks the stand for them once, so
the start of a run can warn about a calibration past its due date and the certificate
can print where each result's traceability comes from.
"""

from __future__ import annotations

import datetime as dt
import re
from collections.abc import Mapping
from typing import Any

from bench.core.config import StandSettings, Traced, stated_traceability

__all__ = ["Traced", "overdue", "overdue_warning", "traced_items"]

#: instruments whose absence of a calibration breaks the chain to the SI (by stand role)
MEASURING_ROLES = ("counter", "dmm")


def traced_items(stand: StandSettings | Mapping[str, Any]) -> list[Traced]:
    """Every instrument of the stand (with or without a stated calibration) and every
    entry of its `traceability:` list: of the parsed stand, or of a run directory's copy
    of the stand file read back (the certificate's)."""
    if isinstance(stand, StandSettings):
        return list(stand.traced)
    return list(stated_traceability(stand))


def overdue(stand: StandSettings | Mapping[str, Any], on: dt.date) -> list[Traced]:
    return [t for t in traced_items(stand) if t.overdue(on)]


def overdue_warning(t: Traced) -> str:
    serial = f", serial {t.stated_serial}" if t.stated_serial else ""
    return (f"WARNING: {t.item}{serial} ({t.where}.calibration): calibration certificate "
            f"{t.certificate} was due on {t.due.isoformat() if t.due else '?'}; the "
            "certificate of this run will say so")


# -- identities: the serial each instrument reported -------------------------------------

_SERIAL_WORD = re.compile(r"\bserial(?: number)?[ :=]+([^\s,;]+)", re.IGNORECASE)
_NO_SERIAL = {"", "0", "none", "unknown", "n/a", "na", "-"}


def serial_of(identity: Any) -> str | None:
    """The serial an instrument reported in its identity: `serial X` in the text (drive
    identity objects, a FOG's configured identity), else the third field of an IEEE 488.2
    `*IDN?` answer (maker,model,serial,firmware). None when it gave none (or 0, which the
    CiA 301 identity object 0x1018:4 reads when the maker set none)."""
    text = str(identity or "").split("; read back:")[0]
    found = _SERIAL_WORD.search(text)
    if found:
        serial = found.group(1).strip()
    else:
        fields = [f.strip() for f in text.split(";")[0].split(",")]
        serial = fields[2] if len(fields) >= 4 else ""
    return None if serial.casefold() in _NO_SERIAL else serial


def identity_problems(instruments: Mapping[str, Any]) -> list[str]:
    """Instruments a value rests on whose identity does not single them out: no serial
    reported, or one serial reported by two instruments of one model (ISO/IEC 17025
    6.4.13 a: every item of equipment uniquely identified)."""
    problems: list[str] = []
    seen: dict[tuple[str, str], list[str]] = {}
    for axis, roles in instruments.items():
        if not isinstance(roles, Mapping):
            continue
        for role, ident in roles.items():
            if role.endswith("_reference"):
                continue    # a reference input, traced in the traceability list
            serial = serial_of(ident)
            where = f"{role} of {axis}"
            if serial is None:
                problems.append(f"the {where} reported no serial number")
                continue
            maker = str(ident).split(";")[0].split(",")[0].strip()
            seen.setdefault((maker, serial), []).append(where)
    for (_maker, serial), wheres in seen.items():
        if len(wheres) > 1:
            problems.append(f"the {', '.join(wheres)} report one serial ({serial}) of one "
                            "maker: two instruments cannot share it")
    return problems


#: roles that answer no identity query: their serial is the stand file's (and said so)
DECLARED_IDENTITY_ROLES = ("fog",)


def with_declared_serials(instruments: Mapping[str, Any],
                          stand: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """The identities as reported, with the stand file's serial added for an instrument
    that answers no identity query (a FOG), marked as stated, not read back."""
    out: dict[str, dict[str, Any]] = {}
    axes = stand.get("axes") or {}
    for axis, roles in instruments.items():
        if not isinstance(roles, Mapping):
            continue
        out[axis] = dict(roles)
        for role in DECLARED_IDENTITY_ROLES:
            spec = (axes.get(axis) or {}).get(role) if isinstance(axes, Mapping) else None
            if role in roles and isinstance(spec, Mapping) and spec.get("serial") \
                    and serial_of(roles[role]) is None:
                head, sep, tail = str(roles[role]).partition("; read back:")
                out[axis][role] = (f"{head}; serial {spec['serial']} (as the stand file "
                                   f"states; it answers no identity query){sep}{tail}")
    return out
