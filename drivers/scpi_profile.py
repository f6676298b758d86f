"""What the drift-pulse instruments' drivers share: a model's profile (`InstrumentProfile`,
found by the name stand files use) and a driver base (`ProfiledInstrument`) that opens
every model the same way: known idle state, empty error queue, the identity it should have."""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Generic, Self, TypeVar, cast

from drivers.clock import Clock
from drivers.scpi import IDN, RawCallback, ScpiInstrument, Words
from drivers.transport import Transport

T = TypeVar("T")


@dataclass(frozen=True, kw_only=True)
class InstrumentProfile:
    """One model of an instrument family; a family's profile adds its limits."""

    model: str                   # as stand files spell it: "keysight-34465a"
    maker: str
    description: str
    words: Words                 # the model's SCPI words by role (a dataclass of Commands)
    idn_pattern: str | None      # what *IDN? must match (None: not checked)
    notes: str = ""              # where the real syntax is unsure
    #: the manual and sections the words were checked against, or "unverified"
    manual: str = "unverified"
    idn: str = ""                # what the model's twin answers to *IDN?


P = TypeVar("P", bound=InstrumentProfile)


def lookup_profile(profiles: Mapping[str, T], model: str, what: str) -> T:
    """The profile of a model as stand files spell it (`keysight-34465a`)."""
    try:
        return profiles[model.strip().lower()]
    except KeyError:
        raise KeyError(f"unknown {what} model {model!r}; known: "
                       f"{', '.join(sorted(profiles))}") from None


class ProfiledInstrument(ScpiInstrument, Generic[P]):
    """A driver whose models differ only by their profile (words, identity, limits).

    A subclass sets `error_kinds` (its family, `ErrorKinds.family`), `kind`, `stand_key`
    and `profiles`; opening and the identity check are then the same for every model.
    """

    #: names the instrument in messages and in the unknown-model error: "DMM"
    kind: ClassVar[str] = "instrument"
    #: the stand file's key for the model, named when *IDN? disagrees: "dmm"
    stand_key: ClassVar[str] = "instrument"
    #: the models the driver knows, by the name stand files use
    profiles: ClassVar[Mapping[str, InstrumentProfile]] = {}

    def __init__(self, resource: str, profile: P, clock: Clock, *,
                 raw: RawCallback | None = None, command_timeout_s: float = 2.0,
                 visa_library: str = "@py", transport: Transport | None = None) -> None:
        self.profile = profile
        self.words = profile.words
        self.clock = clock
        super().__init__(resource, visa_library=visa_library, raw=raw,
                         command_timeout_s=command_timeout_s,
                         name=f"{self.kind} {profile.model} at {resource}",
                         transport=transport)

    @classmethod
    def open(cls, resource: str, model: str | P, clock: Clock, *,
             raw: RawCallback | None = None, check_identity: bool = True,
             visa_library: str = "@py", **options: Any) -> Self:
        """Open, bring to a known idle state, check it is the model named.

        `options` go to the constructor (e.g. the digitizer's `timeout_margin_s`). On
        failure the link is closed and the family's error raised.
        """
        # the class's profiles are all of its own profile type (a ClassVar cannot say P)
        profile: P = (cast(P, lookup_profile(cls.profiles, model, cls.kind))
                      if isinstance(model, str) else model)
        inst = cls(resource, profile, clock, raw=raw, visa_library=visa_library, **options)
        pattern = profile.idn_pattern if check_identity else None
        try:
            with inst.recovering():
                inst.resync()
                inst.drain_errors()
                if pattern:
                    idn = inst.identify()
                    if not re.search(pattern, idn, re.IGNORECASE):
                        raise cls.error_kinds.base(
                            f"{inst.name}: *IDN? says {idn!r}, which is not a "
                            f"{profile.model}: check the stand file's {cls.stand_key} "
                            f"model", command=IDN.text())
        except BaseException:
            inst.close()
            raise
        return inst
