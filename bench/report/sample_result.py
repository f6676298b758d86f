"""A hand-made result.json, typed (issue 60): the frame a kind's sample result states
(`bench.kind.HasSampleResult`, procedures/<kind>/sample.py) around the kind's own part,
for previews of the certificate (`python -m bench.app.certificate.sample`) and for tests
whose printed figures are worked out by hand.

Why Structs and not a map: a sample is a result.json the readers decode like any other.
Its frame's keys are spelled here once, and a kind's part is the kind's own result model,
so the sample's figures sit in the very fields its readers decode (a hand-written map had
kept keys the model no longer has). bench/report/codec.py `encode` gives the document the
readers take (builtins in field order).
"""

from __future__ import annotations

from collections.abc import Mapping

import msgspec
from msgspec import UNSET, UnsetType

from drivers.json_types import JsonLike


class FileStated(msgspec.Struct, frozen=True):
    """A file the run read, by name and SHA-256 (`procedure_file`)."""

    name: str
    sha256: str


class StandStated(msgspec.Struct, frozen=True, kw_only=True):
    """The stand as the run reported it, and its stand file (`stand`)."""

    maker: str
    model: str
    serial: str
    location: str | UnsetType = UNSET
    file: str
    sha256: str


class DatesStated(msgspec.Struct, frozen=True):
    """When the run started and was completed (`dates`)."""

    started_utc: str
    completed_utc: str


class RawFileStated(msgspec.Struct, frozen=True):
    """One raw file of the run, hashed (`raw_files[]`)."""

    path: str
    sha256: str
    bytes: int


class SampleResult(msgspec.Struct, frozen=True, kw_only=True):
    """The frame of a hand-made result (CONTRACT §3), in result.json's key order; a kind's
    sample derives from it and adds its part and its `checks` after these fields."""

    schema: str = "bench.result/1"
    procedure: str
    verdict: str
    title: str
    procedure_file: FileStated
    stand: StandStated
    instruments: dict[str, dict[str, str]]
    dates: DatesStated
    conditions: dict[str, str | float]
    certificate: dict[str, str]
    decision_rule: str
    method: Mapping[str, JsonLike]     # the kind's procedure settings, as its file states them
    raw_files: tuple[RawFileStated, ...]
    sessions: int
    aborted: bool = False
