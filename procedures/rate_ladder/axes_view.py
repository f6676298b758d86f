"""CONTRACT §3's per-axis results as the ladder's views read them: the station's result
tables (station.py), the FOG's check values for the records (records.py) and the
certificate's plots (plots.py) read `axes.<axis>.rates[]`, `pairs[]` and the FOG's noise
floor through these protocols: attributes, typed, read-only (issue 45: no view reads
result.json key by key). The ladder's typed result (result.py `LadderResult`) has them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Protocol

from bench.report.result_frame import MalformedResult, ResultFrame
from procedures.rate_ladder.codec import axes_in


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


def axes_of(frame: ResultFrame) -> Mapping[str, AxisRows]:
    """The ladder's own typed axes of a result read once (`ResultFrame`); {} for one whose
    axes are malformed."""
    try:
        return axes_in(frame)
    except MalformedResult:
        return {}
