"""The rate ladder's journal records between its steps and its analysis.

A step writes one of these when its data are complete in the raw files; the analysis
(and a --resume deciding what to keep) reads the same class back, so a field renamed or
forgotten on one side fails on both (issue 12). They are the kind's declarations among
the journal's (bench/core/events.py, issue 61): the journal adds `utc`, `t_s` and
`session`; unknown keys in an older run's events are ignored.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import ClassVar, TypeVar

import msgspec

from bench.core.events import Event, LiveRow
from bench.report.certificate.rounding import MINUS, format_value_u
from drivers.fog import FogCheckpoint

E = TypeVar("E", bound="LadderEvent")


class LadderEvent(Event, frozen=True):
    """Common to the ladder's records: the axis and the unit (one +/- pair) they belong to."""

    axis: str
    unit: str

    @classmethod
    def all_in(cls: type[E], events: Iterable[Event]) -> list[E]:
        return [e for e in events if isinstance(e, cls)]


class StaticRecorded(LadderEvent, tag="static", frozen=True):
    """The FOG at rest for the noise floor (docs/method.md A5): samples fog_from..fog_to."""

    fog_from: int
    fog_to: int
    rate_hz: float
    lost: int = 0
    fog_capture: FogCheckpoint | None = None   # decoder checkpoint before fog_from


class HalfAcquired(LadderEvent, tag="acquire", frozen=True):
    """One half of a +/- pair, complete: N turns timed by the counter (N + 1 zero-mark
    edges) and the FOG samples fog_from..fog_to that bracket them (docs/method.md A1-A3).
    Written last, so a --resume keeps every half that has one (docs/resume.md)."""

    half: int
    set_rate_dps: float
    turns: int
    edges_s: list[float]
    counter_records: list[int]         # the half's lines in the counter's raw log
    fog_from: int
    fog_to: int
    rate_hz: float
    counter_t0_s: float = 0.0          # the counter's start on the FOG's time axis
    counter_t0_u_s: float | None = None
    counter_readback: dict[str, str] = {}
    fog_lost: int = 0
    fog_capture: FogCheckpoint | None = None
    # how counter_t0_s was placed on the FOG's time axis (drivers/time_tie.py): the tie's
    # source, sync period, latency and its u, the sync pulse that started the counter,
    # when it was armed, and the FOG's sample index convention (index n at n / rate_hz
    # from the session's stand-clock zero): all a later analysis needs to re-place the
    # half after a restart, each session on its own axis (docs/resume.md)
    time_tie: dict[str, str | float | None] = {}

    @property
    def sign(self) -> int:
        return 1 if self.set_rate_dps > 0 else -1


class Settled(LadderEvent, tag="settled", omit_defaults=True, frozen=True):
    """The table held the pair's rate within the settle tolerance (drivers/settle.py);
    with the turn's steady ripple set aside, the ripple is stated."""

    STATION_LOG: ClassVar[bool] = True
    rate_dps: float
    rule: str | None = None
    ripple_peak_dps: float | None = None
    ripple_orders: int | None = None
    turns: int | None = None
    worst_residual_dps: float | None = None

    def log_text(self) -> str:
        mag, rate = _magnitude(self.unit), self.rate_dps
        if not mag:
            return f"settled: {self.axis} at {f'{rate:+g}'.replace('-', MINUS)} deg/s"
        sign = MINUS if rate < 0 else "+"
        return (f"settled: {self.axis} at {sign}{mag}"
                + f" (drive reads {rate:.7g} deg/s)".replace("-", MINUS))


class PairDirection(msgspec.Struct, frozen=True, kw_only=True):
    """One direction of a pair's first look, as the station's results table shows it."""

    set_rate_dps: float
    turns: int | None
    rate_error_rel: float
    rate_error_U_rel: float
    rate_instability_rel: float | None
    verdict: str


class ResultRow(LiveRow, frozen=True, kw_only=True):
    """One direction's row on the station's pages, first look (`PairLooked.rows`) or final
    (station.py `result_rows`): k and w0 of the pair, the rate error with its U, sigma,
    the verdict, as result.json holds them; declared once for both."""

    axis: str
    set_rate_dps: float
    k: float | None
    k_U: float | None               # noqa: N815 - result.json's explicit name
    w0_dps: float | None
    w0_U_dps: float | None          # noqa: N815
    rate_error_rel: float | None
    rate_error_U_rel: float | None  # noqa: N815
    rate_instability_rel: float | None
    turns: int | None
    verdict: str | None


class PairLooked(LadderEvent, tag="pair", omit_defaults=True, frozen=True):
    """The analysis worker's first look at a pair (docs/method.md A3: k and w0 with their
    expanded uncertainties, about 95 %; eq. 1 per direction). The line keeps its keys as
    written since issue 12 (`k_u`, `rate_error_u_rel-`: CONTRACT's `_u`, the expanded U,
    bench/report/uncertainty_names.py): older runs read back the same."""

    STATION_LOG: ClassVar[bool] = True
    k: float
    k_U: float = msgspec.field(name="k_u")
    w0_dps: float
    w0_U_dps: float = msgspec.field(name="w0_u_dps")
    rate_error_plus_rel: float | None = msgspec.field(default=None, name="rate_error_rel+")
    rate_error_plus_U_rel: float | None = msgspec.field(default=None,
                                                           name="rate_error_u_rel+")
    rate_error_minus_rel: float | None = msgspec.field(default=None, name="rate_error_rel-")
    rate_error_minus_U_rel: float | None = msgspec.field(default=None,
                                                            name="rate_error_u_rel-")
    directions: list[PairDirection] = []

    def log_text(self) -> str:
        return (f"pair analysed: {self.axis} ±{_magnitude(self.unit)}: k = "
                f"{_value_u(self.k, self.k_U)}, ω0 = "
                f"{_value_u(self.w0_dps, self.w0_U_dps, signed=True)} deg/s")

    def rows(self) -> list[ResultRow]:
        """Per direction: k and w0 of the pair, the rate error with its U, sigma, the
        verdict, as result.json will hold them."""
        return [ResultRow(axis=self.axis, set_rate_dps=d.set_rate_dps, k=self.k,
                          k_U=self.k_U, w0_dps=self.w0_dps, w0_U_dps=self.w0_U_dps,
                          rate_error_rel=d.rate_error_rel,
                          rate_error_U_rel=d.rate_error_U_rel,
                          rate_instability_rel=d.rate_instability_rel, turns=d.turns,
                          verdict=d.verdict) for d in self.directions]

    def live_rows(self) -> list[LiveRow]:
        """The rows as the station's event protocol carries them (bench/core/events.py
        `LiveRow`): the ladder's station.py reads their fields."""
        return list(self.rows())


class PairFailed(LadderEvent, tag="pair_failed", frozen=True):
    STATION_LOG: ClassVar[bool] = True
    error: str

    def log_text(self) -> str:
        return f"pair first look failed: {self.axis} ±{_magnitude(self.unit)} ({self.error})"


def _magnitude(unit: str) -> str:
    """The rate of a unit name ('outer/30dps' -> '30 deg/s')."""
    return unit.split("/", 1)[1].replace("dps", " deg/s") if "/" in unit else ""


def _value_u(value: float, u: float | None, signed: bool = False) -> str:
    """'value ± u' by the certificate's rounding rule (bench/report/certificate/rounding.py)."""
    r = format_value_u(value, u, 1.0, signed=signed)
    return r.joined() if r.u is not None else f"{r.value} (no U)"
