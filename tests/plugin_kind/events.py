"""The dwell's own journal record, declared where the journal codec looks for a kind's
(bench/core/events.py: the kind's package's `events` module)."""

from __future__ import annotations

from typing import ClassVar

from bench.core.events import Event


class Dwelt(Event, tag="dwelt", frozen=True):
    """The kind's own journal record, declared beside its steps (bench/core/events.py)."""

    STATION_LOG: ClassVar[bool] = True
    waited_s: float
