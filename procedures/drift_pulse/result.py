"""The drift-pulse kind's result model: what result.json's `drift` body and the kind's checks
hold (CONTRACT "The drift-pulse procedure", docs/method.md B), as msgspec Structs (issue 60).

Why Structs: the analysis (analysis.py) returns this model, result.json's `drift` body is
its encoding and the certificate, the DCC and the records decode it once (codec.py) and read
attributes, so every key is a field spelled here and nowhere else, and msgspec, not code of
ours, checks a body against it. Each Struct's field order is the body's key order in
result.json, so the file's bytes do not change with the model.

Uncertainty names (bench/report/uncertainty_names.py): the `_u` keys CONTRACT binds are
written out with their explicit twin as a field of its own, `own_u_dph` beside `own_U_dph`
(expanded) and a cycle's `offset_u_s` beside `offset_ustd_s` (standard), so no key is derived
by a rule over names; a body whose twins differ is refused. A figure's coverage factor and
nu_eff are stated beside it, from its budget (docs/method.md D1); `Quantity` gathers value,
U, k, nu_eff and unit for a reader.
"""

from __future__ import annotations

from collections.abc import Sequence

import msgspec
from msgspec import UNSET, UnsetType

from bench.report.budget import Budget, BudgetRecord
from drivers.json_types import JsonValue

DPH = "deg/h"


def _missing(key: str) -> ValueError:
    """msgspec's own words for a missing key, so codec.py names it the same way."""
    return ValueError(f"Object missing required field `{key}`")


def _same(value: float, twin: float, key: str, twin_key: str) -> None:
    """A `_u` key and its explicit twin hold one value (uncertainty_names.py)."""
    if value != twin:
        raise ValueError(f"`{twin_key}` {twin!r} differs from `{key}` {value!r}, its twin")


class Quantity(msgspec.Struct, frozen=True, kw_only=True):
    """A reported figure: its value, expanded U, the coverage factor k and nu_eff U was
    computed with (None: no budget states them; nu_eff None is infinite), its unit."""

    value: float
    U: float
    k: float | None
    dof: float | None
    unit: str


def _dof(stated: float | None | UnsetType) -> float | None:
    """nu_eff as stated (None: infinite), None where no budget states it (k None then)."""
    return None if isinstance(stated, UnsetType) else stated


class CycleFigures(msgspec.Struct, frozen=True, kw_only=True, omit_defaults=True):
    """One measuring cycle of one gyro (docs/method.md B)."""

    drift_dph: float               # edges at the pooled start offset (the estimate used)
    drift_nominal_dph: float       # edges at the nominal sample times (the paper's integrator)
    u_int_vs: float                # U_int, the signed integral at the corrected edges, V s
    #: the same U_int under the name the naming rule gave it (it read `u_int` as an
    #: uncertainty); kept, so result.json's keys do not change
    ustd_int_vs: float
    amplitude_dps: float           # fitted precession amplitude a
    offset_s: float                # this cycle's own fitted start offset
    offset_u_s: float              # its standard uncertainty (CONTRACT's key)
    offset_ustd_s: float           # the same, its explicit name
    residual_rms_v: float
    t_start_s: float
    table_deg: float

    def __post_init__(self) -> None:
        _same(self.u_int_vs, self.ustd_int_vs, "u_int_vs", "ustd_int_vs")
        _same(self.offset_u_s, self.offset_ustd_s, "offset_u_s", "offset_ustd_s")


class PositionFigures(msgspec.Struct, frozen=True, kw_only=True, omit_defaults=True):
    """The cycles at one platform position: a budget input with its standard uncertainty
    s / sqrt(n) and n - 1 degrees of freedom, no U of its own (docs/method.md D1, D2)."""

    table_deg: float
    cycles: int
    mean_dph: float
    std_dph: float
    mean_ustd_dph: float
    dof: int
    drifts_dph: tuple[float, ...]


class StartOffsetFigures(msgspec.Struct, frozen=True, kw_only=True, omit_defaults=True):
    """The digitizer's start offset against the pulses, pooled over an axis's cycles."""

    offset_s: float
    offset_u_s: float              # expanded, t_95.45(cycles - 1) u (docs/method.md D1)
    offset_U_s: float              # the same, its explicit name  # noqa: N815
    offset_samples: float
    detected: bool                 # more than 3 standard uncertainties from zero
    cycles: int

    def __post_init__(self) -> None:
        _same(self.offset_u_s, self.offset_U_s, "offset_u_s", "offset_U_s")


class ExampleCycle(msgspec.Struct, frozen=True, kw_only=True, omit_defaults=True):
    """One cycle for the certificate's plot: U(t) and the running signed integral, from the
    first pulse edge, decimated (docs/method.md B)."""

    t_s: tuple[float, ...]
    u_v: tuple[float, ...]
    integral_vs: tuple[float, ...]
    tc_s: float
    note: str


def budget_of(budgets: Sequence[BudgetRecord], key: str) -> Budget | None:
    """The budget of result key `key` (`own_dph`, `azimuth_deg`...), None if none states it."""
    return next((b.budget() for b in budgets if b.key == key), None)


class AxisFigures(msgspec.Struct, frozen=True, kw_only=True, omit_defaults=True):
    """One gyro's own and apparent drift, each U = k(nu_eff) u_c of its budget (docs/method.md
    B, D1); a vertical gyro's apparent drift is 15.041 sin(latitude), computed (U 0)."""

    own_dph: float
    own_u_dph: float
    own_U_dph: float                   # noqa: N815 - the explicit twin of own_u_dph
    apparent_dph: float
    apparent_u_dph: float
    apparent_U_dph: float              # noqa: N815
    own_nominal_edges_dph: float       # at the nominal edges, for comparison
    apparent_nominal_edges_dph: float
    amplitude_dps: float
    vertical: bool
    start_offset: StartOffsetFigures
    budgets: tuple[BudgetRecord, ...]
    positions: tuple[PositionFigures, ...]
    cycles: tuple[CycleFigures, ...]
    example_cycle: ExampleCycle | None = None
    # the k and nu_eff of each U, from its budget (docs/method.md D1); absent without one
    own_coverage_factor: float | None = None
    own_dof_eff: float | None | UnsetType = UNSET     # None: infinite
    apparent_coverage_factor: float | None = None
    apparent_dof_eff: float | None | UnsetType = UNSET     # None: infinite

    def __post_init__(self) -> None:
        _same(self.own_u_dph, self.own_U_dph, "own_u_dph", "own_U_dph")
        _same(self.apparent_u_dph, self.apparent_U_dph, "apparent_u_dph", "apparent_U_dph")

    @property
    def own_budget(self) -> Budget | None:
        return budget_of(self.budgets, "own_dph")

    @property
    def apparent_budget(self) -> Budget | None:
        return budget_of(self.budgets, "apparent_dph")

    @property
    def own(self) -> Quantity:
        return Quantity(value=self.own_dph, U=self.own_U_dph, k=self.own_coverage_factor,
                        dof=_dof(self.own_dof_eff), unit=DPH)

    @property
    def apparent(self) -> Quantity:
        return Quantity(value=self.apparent_dph, U=self.apparent_U_dph,
                        k=self.apparent_coverage_factor,
                        dof=_dof(self.apparent_dof_eff), unit=DPH)


class PlatformFigures(msgspec.Struct, frozen=True, kw_only=True):
    """The platform azimuth of the X input axis and the horizontal Earth rate, from the two
    horizontal gyros' apparent drifts (docs/method.md B): `DriftFigures.platform`, a view of
    the body's keys for the readers."""

    azimuth_deg: float
    azimuth_U_deg: float                   # noqa: N815
    earth_horizontal_dph: float            # |(app_x, app_y)|, measured
    earth_horizontal_U_dph: float          # noqa: N815
    earth_horizontal_consistent: bool      # within U of 15.041 cos(latitude)


#: the platform's keys, all present (with x and y) or none
_PLATFORM_KEYS = ("azimuth_deg", "azimuth_u_deg", "azimuth_U_deg", "earth_horizontal_dph",
                  "earth_horizontal_u_dph", "earth_horizontal_U_dph",
                  "earth_horizontal_consistent")


class DriftFigures(msgspec.Struct, frozen=True, kw_only=True, omit_defaults=True):
    """result.json's `drift` body: every gyro's figures, the site latitude and the expected
    horizontal Earth rate, the platform's azimuth and Earth rate (with x and y), their
    budgets; or, when the analysis could not compute them, why (`not_computed`, no
    figures)."""

    axes: dict[str, AxisFigures]
    latitude_deg: float | None = None
    earth_horizontal_expected_dph: float | None = None     # W_h = 15.041 cos(latitude) (B)
    azimuth_deg: float | None = None
    azimuth_u_deg: float | None = None
    azimuth_U_deg: float | None = None                     # noqa: N815
    earth_horizontal_dph: float | None = None
    earth_horizontal_u_dph: float | None = None
    earth_horizontal_U_dph: float | None = None            # noqa: N815
    earth_horizontal_consistent: bool | None = None
    budgets: tuple[BudgetRecord, ...] = ()   # of the azimuth and W_h (docs/method.md B)
    azimuth_coverage_factor: float | None = None
    azimuth_dof_eff: float | None | UnsetType = UNSET     # None: infinite
    earth_horizontal_coverage_factor: float | None = None
    earth_horizontal_dof_eff: float | None | UnsetType = UNSET     # None: infinite
    not_computed: str | None = None

    def __post_init__(self) -> None:
        if self.not_computed is not None:
            return
        for key in ("latitude_deg", "earth_horizontal_expected_dph"):
            if getattr(self, key) is None:
                raise _missing(key)
        present = [getattr(self, k) is not None for k in _PLATFORM_KEYS]
        if any(present) and not all(present):
            raise _missing(_PLATFORM_KEYS[present.index(False)])
        if self.azimuth_u_deg is not None and self.azimuth_U_deg is not None:
            _same(self.azimuth_u_deg, self.azimuth_U_deg, "azimuth_u_deg", "azimuth_U_deg")
        if self.earth_horizontal_u_dph is not None and self.earth_horizontal_U_dph is not None:
            _same(self.earth_horizontal_u_dph, self.earth_horizontal_U_dph,
                  "earth_horizontal_u_dph", "earth_horizontal_U_dph")

    @classmethod
    def failed(cls, reason: str) -> DriftFigures:
        """No figures: the analysis refused the records (the run is then incomplete)."""
        return cls(axes={}, not_computed=reason)

    @property
    def platform(self) -> PlatformFigures | None:
        """The azimuth and horizontal Earth rate, present only with both x and y."""
        if (self.azimuth_deg is None or self.azimuth_U_deg is None
                or self.earth_horizontal_dph is None or self.earth_horizontal_U_dph is None
                or self.earth_horizontal_consistent is None):
            return None
        return PlatformFigures(azimuth_deg=self.azimuth_deg, azimuth_U_deg=self.azimuth_U_deg,
                               earth_horizontal_dph=self.earth_horizontal_dph,
                               earth_horizontal_U_dph=self.earth_horizontal_U_dph,
                               earth_horizontal_consistent=self.earth_horizontal_consistent)

    @property
    def azimuth_budget(self) -> Budget | None:
        return budget_of(self.budgets, "azimuth_deg")

    @property
    def earth_budget(self) -> Budget | None:
        return budget_of(self.budgets, "earth_horizontal_dph")


# -- the method as run --------------------------------------------------------------------------

class DriftMethod(msgspec.Struct, frozen=True, kw_only=True):
    """result.json's `method`: how this run measured (docs/method.md B), the pulse, site and
    tolerance blocks as the procedure file states them."""

    method: str = "docs/method.md B: alternating-sign controlled precession"
    pulse: dict[str, JsonValue]
    timing_cycles: int
    cycles_per_position: int
    positions_deg: tuple[float, ...]
    sample_rate_hz: float
    aperture_s: float
    site: dict[str, JsonValue]
    tolerance: dict[str, JsonValue]


# -- the checks -------------------------------------------------------------------------------

class OwnDriftCheck(msgspec.Struct, frozen=True, kw_only=True):
    """A gyro's own drift against the procedure's tolerance, judged under its decision rule
    (bench/report/conformity.py)."""

    axis: str
    quantity: str = "own_drift"
    unit: str = DPH
    value_dph: float
    u_dph: float
    U_dph: float                   # noqa: N815 - the explicit twin of u_dph
    tolerance_dph: float
    rule: str
    verdict: str
    reason: str
    capability_ratio: float        # U / tolerance
    capability_ok: bool


class EarthRateCheck(msgspec.Struct, frozen=True, kw_only=True):
    """The measured horizontal Earth rate against 15.041 cos(latitude), within its U: a
    consistency check of k_as and the levelling, not conformity (docs/method.md B)."""

    axis: str = "x,y"
    quantity: str = "earth_horizontal_rate"
    unit: str = DPH
    value_dph: float
    u_dph: float
    U_dph: float                   # noqa: N815
    expected_dph: float
    rule: str = "consistency"
    verdict: str
    reason: str

    @classmethod
    def of(cls, value_dph: float, U_dph: float, expected_dph: float,  # noqa: N803
           consistent: bool) -> EarthRateCheck:
        diff = abs(value_dph - expected_dph)
        return cls(value_dph=value_dph, u_dph=U_dph, U_dph=U_dph, expected_dph=expected_dph,
                   verdict="pass" if consistent else "fail",
                   reason=f"|measured - 15.041 cos(latitude)| = {diff:.2g} deg/h "
                          f"{'<=' if consistent else '>'} U = {U_dph:.2g} deg/h")


DriftCheck = OwnDriftCheck | EarthRateCheck


class DriftBody(msgspec.Struct, frozen=True, kw_only=True):
    """What a drift run's result.json holds after the frame, in its key order: the figures,
    then the corrections applied (issue 58; absent: none, the document as before)."""

    drift: DriftFigures
    corrections: list[JsonValue] | UnsetType = UNSET    # as the corrections file states them
