"""What the drift-pulse instruments' drivers share: a model's profile by name, and the
opening handshake (known idle state, empty error queue, the identity it should have)."""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import TypeVar

from drivers.scpi import IDN, InstrumentError, ScpiInstrument

P = TypeVar("P")


def lookup_profile(profiles: Mapping[str, P], model: str, what: str) -> P:
    """The profile of a model as stand files spell it (`keysight-34465a`)."""
    try:
        return profiles[model.strip().lower()]
    except KeyError:
        raise KeyError(f"unknown {what} model {model!r}; known: "
                       f"{', '.join(sorted(profiles))}") from None


def handshake(inst: ScpiInstrument, idn_pattern: str | None, model: str, what: str,
              error: type[InstrumentError]) -> None:
    """Bring a just-opened instrument to a known idle state and check its identity;
    on failure close it and raise (the caller's open() stays a one-liner)."""
    try:
        with inst.recovering():
            inst.resync()
            inst.drain_errors()
            if idn_pattern:
                idn = inst.ask(IDN)
                if not re.search(idn_pattern, idn, re.IGNORECASE):
                    raise error(f"{inst.name}: *IDN? says {idn!r}, which is not a {model}: "
                                f"check the stand file's {what} model", command=IDN.text())
    except BaseException:
        inst.close()
        raise
