"""CONTRACT §3's per-axis results as the kind-neutral pages read them: the station's result
tables and the records' FOG check values (`axes.<axis>.rates[]`, `pairs[]`, the FOG's
noise floor).

Those pages live under bench/, which names no procedure kind, yet must not read
result.json key by key (issue 45). So the kind whose result has such axes hands out its
own typed result (`ShowsAxes`, asked of its records part by isinstance, like the
capabilities in bench/core/registry.py), and the
protocols below are all the pages may ask of it: attributes, typed, read-only. A kind
without such axes answers nothing, and the pages show its declared figures instead.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Protocol, runtime_checkable

from bench.core.registry import installed_records
from drivers.json_types import JsonObject


class RateRow(Protocol):
    """One commanded rate and direction (`axes.<axis>.rates[]`, docs/method.md A1-A2)."""

    @property
    def set_rate_dps(self) -> float: ...
    @property
    def turns(self) -> int | None: ...
    @property
    def rate_error_rel(self) -> float | None: ...
    @property
    def rate_error_U_rel(self) -> float | None: ...
    @property
    def rate_instability_rel(self) -> float | None: ...
    @property
    def rate_instability_U_rel(self) -> float | None: ...
    @property
    def rate_instability_upper_rel(self) -> float | None: ...
    @property
    def rate_instability_lower_rel(self) -> float | None: ...
    @property
    def rate_instability_floor_rel(self) -> float | None: ...
    @property
    def rate_instability_resolved(self) -> bool | None: ...
    @property
    def verdict(self) -> str | None: ...


class PairRow(Protocol):
    """One +/- pair's FOG cross-calibration (`axes.<axis>.pairs[]`, docs/method.md A3)."""

    @property
    def rate_dps(self) -> float: ...
    @property
    def k(self) -> float | None: ...
    @property
    def k_U(self) -> float | None: ...
    @property
    def w0_dps(self) -> float | None: ...
    @property
    def w0_U_dps(self) -> float | None: ...


class FloorRow(Protocol):
    """The FOG at rest (docs/method.md A5): its record's size, spread, mean and Allan
    deviation."""

    @property
    def samples(self) -> int | None: ...
    @property
    def sample_std_dps(self) -> float | None: ...
    @property
    def mean_dps(self) -> float | None: ...
    @property
    def allan_dev_dps(self) -> Sequence[float]: ...


class AxisRows(Protocol):
    """One axis: its rates, its pairs and its FOG's noise floor (None: not measured)."""

    @property
    def rates(self) -> Sequence[RateRow]: ...
    @property
    def pairs(self) -> Sequence[PairRow]: ...
    @property
    def noise_floor(self) -> FloorRow | None: ...


@runtime_checkable
class ShowsAxes(Protocol):
    """A kind's records part that reads CONTRACT §3's per-axis rates and pairs, typed."""

    def axes_view(self, result: Mapping[str, object]) -> Mapping[str, AxisRows]:
        """Axis name -> its rates, pairs and noise floor ({} if the result has none or
        they are malformed)."""
        ...


def axes_of(result: JsonObject, kind: str | None) -> Mapping[str, AxisRows]:
    """The result's axes as its kind reads them ({} when the kind is not installed here,
    has no such axes, or the result's are malformed)."""
    records = installed_records(kind)
    return records.axes_view(result) if isinstance(records, ShowsAxes) else {}
