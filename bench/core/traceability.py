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
from dataclasses import dataclass

from bench.core.config import StandSettings, Traced, stated_traceability
from bench.core.yamlfile import YamlValue

__all__ = ["Identities", "Traced", "overdue", "overdue_warning", "traced_items"]

#: what each instrument reported, per axis and role (result.json's `instruments` block,
#: decoded by bench/core/settings_codec.py; the run's `identity` events)
Identities = Mapping[str, Mapping[str, str]]
#: a stand file as read back from a run directory's copy (YAML)
StandCopy = Mapping[str, YamlValue]

#: instruments whose absence of a calibration breaks the chain to the SI (by stand role)
MEASURING_ROLES = ("counter", "dmm")


def traced_items(stand: StandSettings | StandCopy) -> list[Traced]:
    """Every instrument of the stand (with or without a stated calibration) and every
    entry of its `traceability:` list: of the parsed stand, or of a run directory's copy
    of the stand file read back (the certificate's)."""
    if isinstance(stand, StandSettings):
        return list(stand.traced)
    return list(stated_traceability(stand))


def overdue(stand: StandSettings | StandCopy, on: dt.date) -> list[Traced]:
    return [t for t in traced_items(stand) if t.overdue(on)]


def overdue_warning(t: Traced) -> str:
    serial = f", serial {t.stated_serial}" if t.stated_serial else ""
    return (f"WARNING: {t.item}{serial} ({t.where}.calibration): calibration certificate "
            f"{t.certificate} was due on {t.due.isoformat() if t.due else '?'}; the "
            "certificate of this run will say so")


# -- identities: the serial each instrument reported -------------------------------------

_SERIAL_WORD = re.compile(r"\bserial(?: number)?[ :=]+([^\s,;]+)", re.IGNORECASE)
_NO_SERIAL = {"", "0", "none", "unknown", "n/a", "na", "-"}


def serial_of(identity: str | None) -> str | None:
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


def identity_problems(instruments: Identities) -> list[str]:
    """Items a value rests on whose identity does not single them out (ISO/IEC 17025
    6.4.13 a: every item of equipment uniquely identified): an instrument that reported no
    serial, one serial reported by two instruments of one model (the FOG included, by the
    serial it reported or the stand file states for it), and, when `instruments` came from
    `with_declared_serials` (which keeps the stand it read), each entry of the stand's
    `traceability:` list without a serial of its own, one naming several items, or one
    sharing a serial with another item (`reference_problems`)."""
    problems: list[str] = []
    seen: dict[tuple[str, str], list[str]] = {}
    for axis, roles in instruments.items():
        for role, ident in roles.items():
            if role.endswith("_reference"):
                continue    # a reference input, traced in the traceability list
            serial = serial_of(ident)
            where = f"{role} of {axis}"
            if serial is None:
                problems.append(f"the {where} reported no serial number")
                continue
            maker = ident.split(";")[0].split(",")[0].strip()
            seen.setdefault((maker, serial), []).append(where)
    for (_maker, serial), wheres in seen.items():
        if len(wheres) > 1:
            problems.append(f"the {', '.join(wheres)} report one serial ({serial}) of one "
                            "maker: two instruments cannot share it")
    if isinstance(instruments, DeclaredIdentities):
        problems += reference_problems(instruments.stand, instruments)
    return problems


#: a serial that lists several items ("SIM-BS5-01/02", "A1, A2", "X and Y"): each item of
#: equipment is listed on its own with its own serial
_SEVERAL = re.compile(r"[/,;&+]|\band\b", re.IGNORECASE)


def reference_problems(stand: StandCopy, instruments: Identities | None = None) -> list[str]:
    """The stand's `traceability:` entries (references and sensors the bench reads no
    identity from) that do not identify one item: no serial, a serial naming several
    items, or a serial another entry or a reporting instrument also carries."""
    problems: list[str] = []
    owners: dict[str, list[tuple[str, bool]]] = {}     # serial: (who, a list entry)
    for axis, roles in (instruments or {}).items():
        for role, ident in roles.items():
            serial = None if role.endswith("_reference") else serial_of(ident)
            if serial:
                owners.setdefault(serial.casefold(), []).append((f"the {role} of {axis}",
                                                                 False))
    for t in stated_traceability(stand):
        if not t.where.startswith("traceability"):
            continue
        what = f"{t.item} ({t.where})"
        serial = (t.stated_serial or "").strip()
        if not serial or serial.casefold() in _NO_SERIAL:
            problems.append(f"{what} states no serial number: the item cannot be told from "
                            "another of its kind")
        elif _SEVERAL.search(serial):
            problems.append(f"{what} states one serial for several items ({serial}): list "
                            "each item with its own serial and certificate")
        else:
            owners.setdefault(serial.casefold(), []).append((what, True))
    for serial, found in owners.items():
        if len(found) > 1 and any(listed for _, listed in found):
            problems.append(f"{'; '.join(w for w, _ in found)} carry one serial ({serial}): "
                            "two items cannot share it")
    return problems


class DeclaredIdentities(dict[str, dict[str, str]]):
    """The identities as reported, with the stand file they were completed from (so the
    identity check also reads the stand's traceability list)."""

    def __init__(self, identities: Mapping[str, dict[str, str]], stand: StandCopy) -> None:
        super().__init__(identities)
        self.stand: StandCopy = stand


#: roles that answer no identity query: their serial is the stand file's (and said so)
DECLARED_IDENTITY_ROLES = ("fog",)


def _stated_serial(stand: StandCopy, axis: str, role: str) -> YamlValue:
    """The serial the stand copy states for an axis's instrument (None: it states none)."""
    axes = stand.get("axes")
    block = axes.get(axis) if isinstance(axes, dict) else None
    spec = block.get(role) if isinstance(block, dict) else None
    return spec.get("serial") if isinstance(spec, dict) else None


def with_declared_serials(instruments: Identities, stand: StandCopy) -> DeclaredIdentities:
    """The identities as reported, with the stand file's serial added for an instrument
    that answers no identity query (a FOG), marked as stated, not read back."""
    out: dict[str, dict[str, str]] = {}
    for axis, roles in instruments.items():
        out[axis] = dict(roles)
        for role in DECLARED_IDENTITY_ROLES:
            serial = _stated_serial(stand, axis, role)
            if role in roles and serial and serial_of(roles[role]) is None:
                head, sep, tail = roles[role].partition("; read back:")
                out[axis][role] = (f"{head}; serial {serial} (as the stand file "
                                   f"states; it answers no identity query){sep}{tail}")
    return DeclaredIdentities(out, stand)


# -- the identity the stand states against the one the instrument reports ----------------

def same_serial(stated: str, reported: str) -> bool:
    """One serial written two ways: a drive's 0x1018:4 is a number (UNSIGNED32) that a
    stand states as text ("41001", "0xA029"); an *IDN? serial compares as text, case
    aside."""
    a, b = stated.strip(), reported.strip()
    if a.casefold() == b.casefold():
        return True
    try:
        return int(a, 0) == int(b, 0)
    except ValueError:
        return False


@dataclass(frozen=True)
class IdentityMismatch:
    """The stand file names one instrument, another answered (ISO/IEC 17025 6.4.13 a)."""

    where: str          # the stand key, e.g. axes.outer.counter.serial
    stated: str
    reported: str
    query: str          # how the instrument was asked

    @property
    def text(self) -> str:
        return (f"{self.where}: the stand file states serial {self.stated}, the instrument "
                f"reports {self.reported} ({self.query})")


#: how each role reports its serial (what the certificate and the refusal name)
IDENTITY_QUERIES = {"counter": "*IDN?", "drive": "identity object 0x1018:4",
                    "fog": "?IS"}


def identity_mismatches(stand: StandSettings, identities: Identities) -> list[IdentityMismatch]:
    """Every instrument whose reported serial differs from the serial its stand block
    states. An instrument that reports none is not a mismatch (identity_problems says
    so); a FOG that answers no identity query keeps the stand's serial, stated."""
    out: list[IdentityMismatch] = []
    for axis, spec in stand.axes.items():
        got = identities.get(axis) or {}
        stated_by_role = {"counter": spec.counter.serial if spec.counter else None,
                          "drive": spec.drive.serial,
                          "fog": spec.fog.serial if spec.fog else None}
        for role, stated in stated_by_role.items():
            reported = serial_of(got.get(role)) if got.get(role) else None
            if stated and reported and "as the stand file states" not in got.get(role, "") \
                    and not same_serial(str(stated), reported):
                out.append(IdentityMismatch(f"axes.{axis}.{role}.serial", str(stated),
                                            reported, IDENTITY_QUERIES[role]))
    return out
