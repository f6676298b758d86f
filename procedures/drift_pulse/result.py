"""The drift-pulse kind's result, typed: what result.json's `drift` body and the kind's
checks hold (CONTRACT "The drift-pulse procedure", docs/method.md B), and the one place that
spells their keys.

Why one module: the analysis (analysis.py) builds these values, `to_json` writes them into
result.json, and the certificate, the DCC and the records call `from_json` once on the dict
they are given and read attributes from then on, so a key is spelled here and nowhere else.
`from_json` refuses a malformed body with the key path that is wrong
(`drift.axes.x.positions[1].mean_dph: missing`): a certificate is never built from half a
result.

Uncertainty names (bench/report/uncertainty_names.py): the `_u` keys CONTRACT binds are
expanded (`own_U_dph` here) except a cycle's fitted offset and a position mean's, which are
standard (`_ustd_`). result.json also carries each `_u` key's explicit twin (added when the
document is written) and each figure's coverage factor and nu_eff (derived here from its
budget): `from_json` reads neither, both follow from what it reads.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TypeVar

from bench.report.budget import Budget, budget_from_json

T = TypeVar("T")

#: the body's key in result.json, and the root of every path `from_json` names
ROOT = "drift"


class MalformedResult(ValueError):
    """A result.json drift body that does not hold what the analysis writes."""

    def __init__(self, path: str, problem: str) -> None:
        super().__init__(f"result.json {path}: {problem}")
        self.path = path


# -- reading JSON with the key path at hand ---------------------------------------------------

def _object(node: object, path: str) -> Mapping[str, object]:
    if not isinstance(node, Mapping):
        raise MalformedResult(path, f"expected an object, got {type(node).__name__}")
    return node


def _field(node: Mapping[str, object], key: str, path: str) -> object:
    if key not in node:
        raise MalformedResult(f"{path}.{key}", "missing")
    return node[key]


def _as_number(value: object, path: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise MalformedResult(path, f"expected a number, got {value!r:.40}")
    return value


def _number(node: Mapping[str, object], key: str, path: str) -> float:
    return _as_number(_field(node, key, path), f"{path}.{key}")


def _optional_number(node: Mapping[str, object], key: str, path: str) -> float | None:
    value = node.get(key)
    return None if value is None else _as_number(value, f"{path}.{key}")


def _int(node: Mapping[str, object], key: str, path: str) -> int:
    value = _field(node, key, path)
    if isinstance(value, bool) or not isinstance(value, int):
        raise MalformedResult(f"{path}.{key}", f"expected an integer, got {value!r:.40}")
    return value


def _bool(node: Mapping[str, object], key: str, path: str) -> bool:
    value = _field(node, key, path)
    if not isinstance(value, bool):
        raise MalformedResult(f"{path}.{key}", f"expected true or false, got {value!r:.40}")
    return value


def _text(node: Mapping[str, object], key: str, path: str) -> str:
    value = _field(node, key, path)
    if not isinstance(value, str):
        raise MalformedResult(f"{path}.{key}", f"expected text, got {value!r:.40}")
    return value


def _items(node: Mapping[str, object], key: str, path: str,
           read: Callable[[object, str], T]) -> tuple[T, ...]:
    value = _field(node, key, path)
    if not isinstance(value, list):
        raise MalformedResult(f"{path}.{key}", f"expected a list, got {type(value).__name__}")
    return tuple(read(v, f"{path}.{key}[{i}]") for i, v in enumerate(value))


def _numbers(node: Mapping[str, object], key: str, path: str) -> tuple[float, ...]:
    return _items(node, key, path, _as_number)


def _budget(node: object, path: str) -> Budget:
    budget = budget_from_json(_object(node, path))
    if budget is None:
        raise MalformedResult(path, "not an uncertainty budget (quantity, key, terms)")
    return budget


def _budgets(node: Mapping[str, object], path: str) -> tuple[Budget, ...]:
    return _items(node, "budgets", path, _budget)


def _coverage(budgets: Sequence[Budget], key: str, stem: str) -> dict[str, object]:
    """`<stem>_coverage_factor`, `<stem>_dof_eff` of the budget of figure `key`: the k and
    nu_eff its U was computed with, stated beside it (docs/method.md D1)."""
    budget = budget_of(budgets, key)
    if budget is None:
        return {}
    return {f"{stem}_coverage_factor": budget.k, f"{stem}_dof_eff": budget.dof_eff}


def budget_of(budgets: Sequence[Budget], key: str) -> Budget | None:
    """The budget of result key `key` (`own_dph`, `azimuth_deg`...), None if none states it."""
    return next((b for b in budgets if b.key == key), None)


# -- the parts --------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class CycleFigures:
    """One measuring cycle of one gyro (docs/method.md B)."""

    drift_dph: float               # edges at the pooled start offset (the estimate used)
    drift_nominal_dph: float       # edges at the nominal sample times (the paper's integrator)
    u_int_vs: float                # U_int, the signed integral at the corrected edges, V s
    amplitude_dps: float           # fitted precession amplitude a
    offset_s: float                # this cycle's own fitted start offset
    offset_ustd_s: float           # its standard uncertainty (key `offset_u_s`)
    residual_rms_v: float
    t_start_s: float
    table_deg: float

    def to_json(self) -> dict[str, object]:
        return {"drift_dph": float(self.drift_dph),
                "drift_nominal_dph": float(self.drift_nominal_dph),
                "u_int_vs": float(self.u_int_vs), "amplitude_dps": float(self.amplitude_dps),
                "offset_s": float(self.offset_s), "offset_u_s": float(self.offset_ustd_s),
                "residual_rms_v": float(self.residual_rms_v),
                "t_start_s": float(self.t_start_s), "table_deg": float(self.table_deg)}

    @classmethod
    def from_json(cls, node: object, path: str) -> CycleFigures:
        d = _object(node, path)
        return cls(_number(d, "drift_dph", path), _number(d, "drift_nominal_dph", path),
                   _number(d, "u_int_vs", path), _number(d, "amplitude_dps", path),
                   _number(d, "offset_s", path), _number(d, "offset_u_s", path),
                   _number(d, "residual_rms_v", path), _number(d, "t_start_s", path),
                   _number(d, "table_deg", path))


@dataclass(frozen=True, slots=True)
class PositionFigures:
    """The cycles at one platform position: a budget input with its standard uncertainty
    s / sqrt(n) and n - 1 degrees of freedom, no U of its own (docs/method.md D1, D2)."""

    table_deg: float
    cycles: int
    mean_dph: float
    std_dph: float
    mean_ustd_dph: float
    dof: int
    drifts_dph: tuple[float, ...]

    def to_json(self) -> dict[str, object]:
        return {"table_deg": self.table_deg, "cycles": self.cycles, "mean_dph": self.mean_dph,
                "std_dph": self.std_dph, "mean_ustd_dph": self.mean_ustd_dph, "dof": self.dof,
                "drifts_dph": list(self.drifts_dph)}

    @classmethod
    def from_json(cls, node: object, path: str) -> PositionFigures:
        d = _object(node, path)
        return cls(_number(d, "table_deg", path), _int(d, "cycles", path),
                   _number(d, "mean_dph", path), _number(d, "std_dph", path),
                   _number(d, "mean_ustd_dph", path), _int(d, "dof", path),
                   _numbers(d, "drifts_dph", path))


@dataclass(frozen=True, slots=True)
class StartOffsetFigures:
    """The digitizer's start offset against the pulses, pooled over an axis's cycles."""

    offset_s: float
    offset_U_s: float              # expanded, t_95.45(cycles - 1) u (key `offset_u_s`, D1)
    offset_samples: float
    detected: bool                 # more than 3 standard uncertainties from zero
    cycles: int

    def to_json(self) -> dict[str, object]:
        return {"offset_s": self.offset_s, "offset_u_s": self.offset_U_s,
                "offset_samples": self.offset_samples, "detected": self.detected,
                "cycles": self.cycles}

    @classmethod
    def from_json(cls, node: object, path: str) -> StartOffsetFigures:
        d = _object(node, path)
        return cls(_number(d, "offset_s", path), _number(d, "offset_u_s", path),
                   _number(d, "offset_samples", path), _bool(d, "detected", path),
                   _int(d, "cycles", path))


@dataclass(frozen=True, slots=True)
class ExampleCycle:
    """One cycle for the certificate's plot: U(t) and the running signed integral, from the
    first pulse edge, decimated (docs/method.md B)."""

    t_s: tuple[float, ...]
    u_v: tuple[float, ...]
    integral_vs: tuple[float, ...]
    tc_s: float
    note: str

    def to_json(self) -> dict[str, object]:
        return {"t_s": list(self.t_s), "u_v": list(self.u_v),
                "integral_vs": list(self.integral_vs), "tc_s": self.tc_s, "note": self.note}

    @classmethod
    def from_json(cls, node: object, path: str) -> ExampleCycle:
        d = _object(node, path)
        return cls(_numbers(d, "t_s", path), _numbers(d, "u_v", path),
                   _numbers(d, "integral_vs", path), _number(d, "tc_s", path),
                   _text(d, "note", path))


@dataclass(frozen=True, slots=True)
class AxisFigures:
    """One gyro's own and apparent drift, each U = k(nu_eff) u_c of its budget (docs/method.md
    B, D1); a vertical gyro's apparent drift is 15.041 sin(latitude), computed (U 0)."""

    own_dph: float
    own_U_dph: float
    apparent_dph: float
    apparent_U_dph: float
    own_nominal_edges_dph: float       # at the nominal edges, for comparison
    apparent_nominal_edges_dph: float
    amplitude_dps: float
    vertical: bool
    start_offset: StartOffsetFigures
    budgets: tuple[Budget, ...]
    positions: tuple[PositionFigures, ...]
    cycles: tuple[CycleFigures, ...]
    example_cycle: ExampleCycle | None = None

    @property
    def own_budget(self) -> Budget | None:
        return budget_of(self.budgets, "own_dph")

    @property
    def apparent_budget(self) -> Budget | None:
        return budget_of(self.budgets, "apparent_dph")

    def to_json(self) -> dict[str, object]:
        return {
            "own_dph": self.own_dph, "own_u_dph": self.own_U_dph,
            "apparent_dph": self.apparent_dph, "apparent_u_dph": self.apparent_U_dph,
            "own_nominal_edges_dph": self.own_nominal_edges_dph,
            "apparent_nominal_edges_dph": self.apparent_nominal_edges_dph,
            "amplitude_dps": self.amplitude_dps,
            "vertical": self.vertical,
            "start_offset": self.start_offset.to_json(),
            "budgets": [b.to_json() for b in self.budgets],
            "positions": [p.to_json() for p in self.positions],
            "cycles": [c.to_json() for c in self.cycles],
            **({"example_cycle": self.example_cycle.to_json()} if self.example_cycle else {}),
            **_coverage(self.budgets, "own_dph", "own"),
            **_coverage(self.budgets, "apparent_dph", "apparent"),
        }

    @classmethod
    def from_json(cls, node: object, path: str) -> AxisFigures:
        d = _object(node, path)
        example = d.get("example_cycle")
        return cls(
            _number(d, "own_dph", path), _number(d, "own_u_dph", path),
            _number(d, "apparent_dph", path), _number(d, "apparent_u_dph", path),
            _number(d, "own_nominal_edges_dph", path),
            _number(d, "apparent_nominal_edges_dph", path), _number(d, "amplitude_dps", path),
            _bool(d, "vertical", path),
            StartOffsetFigures.from_json(_field(d, "start_offset", path),
                                         f"{path}.start_offset"),
            _budgets(d, path), _items(d, "positions", path, PositionFigures.from_json),
            _items(d, "cycles", path, CycleFigures.from_json),
            None if example is None else ExampleCycle.from_json(example,
                                                                f"{path}.example_cycle"))


@dataclass(frozen=True, slots=True)
class PlatformFigures:
    """The platform azimuth of the X input axis and the horizontal Earth rate, from the two
    horizontal gyros' apparent drifts (docs/method.md B); present only with both x and y."""

    azimuth_deg: float
    azimuth_U_deg: float
    earth_horizontal_dph: float            # |(app_x, app_y)|, measured
    earth_horizontal_U_dph: float
    earth_horizontal_consistent: bool      # within U of 15.041 cos(latitude)

    def to_json(self) -> dict[str, object]:
        return {"azimuth_deg": self.azimuth_deg, "azimuth_u_deg": self.azimuth_U_deg,
                "earth_horizontal_dph": self.earth_horizontal_dph,
                "earth_horizontal_u_dph": self.earth_horizontal_U_dph,
                "earth_horizontal_consistent": self.earth_horizontal_consistent}

    @classmethod
    def from_json(cls, d: Mapping[str, object], path: str) -> PlatformFigures:
        return cls(_number(d, "azimuth_deg", path), _number(d, "azimuth_u_deg", path),
                   _number(d, "earth_horizontal_dph", path),
                   _number(d, "earth_horizontal_u_dph", path),
                   _bool(d, "earth_horizontal_consistent", path))


@dataclass(frozen=True, slots=True)
class DriftFigures:
    """result.json's `drift` body: every gyro's figures, the site latitude and the expected
    horizontal Earth rate, the platform's azimuth (with x and y), their budgets; or, when
    the analysis could not compute them, why (`not_computed`, no figures)."""

    axes: Mapping[str, AxisFigures]
    latitude_deg: float | None
    earth_horizontal_expected_dph: float | None   # W_h = 15.041 cos(latitude) (B)
    platform: PlatformFigures | None = None
    budgets: tuple[Budget, ...] = ()              # of the azimuth and W_h (docs/method.md B)
    not_computed: str | None = None

    @classmethod
    def failed(cls, reason: str) -> DriftFigures:
        """No figures: the analysis refused the records (the run is then incomplete)."""
        return cls({}, None, None, not_computed=reason)

    @property
    def azimuth_budget(self) -> Budget | None:
        return budget_of(self.budgets, "azimuth_deg")

    @property
    def earth_budget(self) -> Budget | None:
        return budget_of(self.budgets, "earth_horizontal_dph")

    def to_json(self) -> dict[str, object]:
        """CONTRACT's drift keys; the azimuth and Earth-rate keys only with both x and y."""
        if self.not_computed is not None:
            return {"axes": {}, "not_computed": self.not_computed}
        out: dict[str, object] = {
            "axes": {g: ax.to_json() for g, ax in self.axes.items()},
            "latitude_deg": self.latitude_deg,
            "earth_horizontal_expected_dph": self.earth_horizontal_expected_dph,
        }
        if self.platform is not None:
            out |= self.platform.to_json()
        out["budgets"] = [b.to_json() for b in self.budgets]
        out |= _coverage(self.budgets, "azimuth_deg", "azimuth")
        out |= _coverage(self.budgets, "earth_horizontal_dph", "earth_horizontal")
        return out

    @classmethod
    def from_json(cls, node: object, path: str = ROOT) -> DriftFigures:
        d = _object(node, path)
        if "not_computed" in d:
            return cls.failed(_text(d, "not_computed", path))
        axes = _object(_field(d, "axes", path), f"{path}.axes")
        return cls({str(g): AxisFigures.from_json(a, f"{path}.axes.{g}")
                    for g, a in axes.items()},
                   _number(d, "latitude_deg", path),
                   _number(d, "earth_horizontal_expected_dph", path),
                   PlatformFigures.from_json(d, path) if "azimuth_deg" in d else None,
                   _budgets(d, path))

    @classmethod
    def of(cls, result: Mapping[str, object]) -> DriftFigures:
        """The drift body of a whole result.json."""
        if ROOT not in result:
            raise MalformedResult(ROOT, "missing")
        return cls.from_json(result[ROOT])


# -- the method as run --------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class DriftMethod:
    """result.json's `method`: how this run measured (docs/method.md B), the pulse, site and
    tolerance blocks as the procedure file states them."""

    pulse: Mapping[str, object]
    timing_cycles: int
    cycles_per_position: int
    positions_deg: tuple[float, ...]
    sample_rate_hz: float
    aperture_s: float
    site: Mapping[str, object]
    tolerance: Mapping[str, object]

    def to_json(self) -> dict[str, object]:
        return {"method": "docs/method.md B: alternating-sign controlled precession",
                "pulse": dict(self.pulse), "timing_cycles": self.timing_cycles,
                "cycles_per_position": self.cycles_per_position,
                "positions_deg": list(self.positions_deg),
                "sample_rate_hz": self.sample_rate_hz, "aperture_s": self.aperture_s,
                "site": dict(self.site), "tolerance": dict(self.tolerance)}


# -- the checks -------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class OwnDriftCheck:
    """A gyro's own drift against the procedure's tolerance, judged under its decision rule
    (bench/report/conformity.py)."""

    axis: str
    value_dph: float
    U_dph: float
    tolerance_dph: float
    rule: str
    verdict: str
    reason: str
    capability_ratio: float        # U / tolerance
    capability_ok: bool

    def to_json(self) -> dict[str, object]:
        return {"axis": self.axis, "quantity": "own_drift", "unit": "deg/h",
                "value_dph": self.value_dph, "u_dph": self.U_dph,
                "tolerance_dph": self.tolerance_dph, "rule": self.rule,
                "verdict": self.verdict, "reason": self.reason,
                "capability_ratio": self.capability_ratio, "capability_ok": self.capability_ok}


@dataclass(frozen=True, slots=True)
class EarthRateCheck:
    """The measured horizontal Earth rate against 15.041 cos(latitude), within its U: a
    consistency check of k_as and the levelling, not conformity (docs/method.md B)."""

    value_dph: float
    U_dph: float
    expected_dph: float
    consistent: bool

    def to_json(self) -> dict[str, object]:
        diff = abs(self.value_dph - self.expected_dph)
        return {"axis": "x,y", "quantity": "earth_horizontal_rate", "unit": "deg/h",
                "value_dph": self.value_dph, "u_dph": self.U_dph,
                "expected_dph": self.expected_dph, "rule": "consistency",
                "verdict": "pass" if self.consistent else "fail",
                "reason": f"|measured - 15.041 cos(latitude)| = {diff:.2g} deg/h "
                          f"{'<=' if self.consistent else '>'} U = {self.U_dph:.2g} deg/h"}


DriftCheck = OwnDriftCheck | EarthRateCheck
