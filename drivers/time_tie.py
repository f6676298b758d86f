"""The time tie: how a counter's start event is placed on the FOG's time axis.

Why it must be explicit: a 53230A reports intervals from its start event, a CNT-91 time
stamps "since a certain start event that is not available for external control"
(CNT-90 series Programmer's Handbook p. 8-72); neither reply says when that was on the
FOG's time axis, and the analysis cuts the FOG record at the zero marks (docs/method.md A3).
On twins sharing one clock the tie came for free; on hardware it needs a physical link.

Sources (stand key `counter.time_tie.source`):

- `fog-sync`: the counter's external trigger (TRIG:SOUR EXT) is driven by the FOG's
  sync output, which pulses at FOG time k * sync_period_s (every n-th sample). The driver
  notes its clock just before and just after INIT is accepted; the first pulse after INIT
  starts the measurement, so the start is the next pulse after that window, plus the
  link's calibrated `latency_s`. When a pulse falls inside the window (plus the host's
  `host_window_s` uncertainty about the FOG's time axis), the pulse is ambiguous and the
  driver re-arms. Residual: latency_u_s (calibration and jitter), in the budget.
- `host-clock`: the start is INIT itself, placed at the middle of the window; its
  uncertainty is half the window (a millisecond on a LAN, far more on a loaded PC). For
  tests and for counters whose reply already is on a known axis; never exact.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from msgspec import Meta, Struct

SOURCES = ("fog-sync", "host-clock")


class TimeTieAmbiguous(ValueError):
    """A sync pulse fell inside the window in which INIT was accepted."""


class TimeTie(Struct, frozen=True, forbid_unknown_fields=True):
    """How the counter's start event sits on the FOG's time axis (module docstring);
    declared once, as the stand's `counter.time_tie:` block (bench/core/schema.py reads
    each key's meaning and unit here)."""

    source: Annotated[Literal["fog-sync", "host-clock"], Meta(
        description="how the counter's start event is placed on the FOG's time axis: "
                    "fog-sync (external trigger from the FOG's sync output) or "
                    "host-clock", extra={"required": True})] = "host-clock"
    sync_period_s: Annotated[float, Meta(
        gt=0, extra={"unit": "s"},
        description="FOG time between sync pulses (pulse k at k * period)")] = 1.0
    latency_s: Annotated[float, Meta(
        ge=0, extra={"unit": "s"},
        description="sync pulse to counter trigger, calibrated")] = 0.0
    latency_u_s: Annotated[float, Meta(
        ge=0, extra={"unit": "s"}, description="its standard uncertainty (with "
                                                "jitter)")] = 0.0
    host_window_s: Annotated[float, Meta(
        ge=0, extra={"unit": "s"},
        description="how well the host knows the FOG's time axis")] = 0.0

    def __post_init__(self) -> None:
        if self.source not in SOURCES:
            raise ValueError(f"time tie source {self.source!r}: one of {', '.join(SOURCES)}")
        if not self.sync_period_s > 0:
            raise ValueError(f"time tie sync_period_s must be > 0, got {self.sync_period_s}")

    @property
    def uses_external_trigger(self) -> bool:
        return self.source == "fog-sync"

    def start_s(self, t_before_s: float, t_after_s: float) -> tuple[float, float]:
        """The start event on the FOG axis and its standard uncertainty, s.

        `t_before_s` .. `t_after_s`: the host clock just before INIT was sent and just
        after the instrument confirmed it. Raises TimeTieAmbiguous (re-arm) for fog-sync
        when a pulse may have come inside that window.
        """
        if self.source == "host-clock":
            return 0.5 * (t_before_s + t_after_s), 0.5 * (t_after_s - t_before_s)
        p = self.sync_period_s
        k0 = math.floor((t_before_s - self.host_window_s) / p)
        k1 = math.floor((t_after_s + self.host_window_s) / p)
        if k0 != k1:
            raise TimeTieAmbiguous(
                f"a FOG sync pulse (every {p:g} s) may have come while INIT was on its way "
                f"({t_before_s:.6f} .. {t_after_s:.6f} s, host window "
                f"{self.host_window_s:g} s)")
        return (k0 + 1) * p + self.latency_s, self.latency_u_s

    def as_record(self) -> dict[str, str | float]:
        return {"source": self.source, "sync_period_s": self.sync_period_s,
                "latency_s": self.latency_s, "latency_u_s": self.latency_u_s,
                "host_window_s": self.host_window_s}
