"""An instrument's calibration certificate as the stand file states it.

A msgspec Struct, declared once with each key's meaning: every instrument block of the
stand (a drive's, a counter's, a FOG's) carries one, and bench/core/schema.py reads the
declaration for `bench validate`, `bench schema` and docs/configuration.md. It lives in
the drivers' layer because a drive's settings (drivers/drive_settings.py) hold one.
"""

from __future__ import annotations

import datetime as dt
from typing import Annotated, Any

from msgspec import Meta, Struct


class Calibration(Struct, frozen=True, forbid_unknown_fields=True):
    """An instrument's or reference's calibration certificate, as the stand states it."""

    certificate: Annotated[str, Meta(description="the calibration certificate's number")]
    issuer: Annotated[str, Meta(description="the laboratory that issued it")]
    #: a file must state it (the schema's Date); None only where read leniently (`of`)
    due: Annotated[dt.date, Meta(description="calibration due date, YYYY-MM-DD")] | None
    traces: Annotated[str, Meta(description="the quantity it traces to SI, e.g. 'time "
                                            "interval to the SI second'")] | None = None

    @classmethod
    def of(cls, d: dict[str, Any] | None) -> Calibration | None:
        """A calibration block read leniently (a traceability entry, a run's copy)."""
        if not isinstance(d, dict):
            return None
        traces = d.get("traces")
        return cls(str(d.get("certificate", "")), str(d.get("issuer", "")),
                   parse_date(d.get("due")), str(traces) if traces is not None else None)


def parse_date(value: object) -> dt.date | None:
    """A date from YAML (a date, or text YYYY-MM-DD); None if it is not one."""
    if isinstance(value, dt.datetime):
        return value.date()
    if isinstance(value, dt.date):
        return value
    if isinstance(value, str):
        try:
            return dt.date.fromisoformat(value.strip())
        except ValueError:
            return None
    return None
