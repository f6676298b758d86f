"""The drift-pulse procedure's uncertainty budgets (EA-4/02 form, bench.report.budget), in the
input quantities themselves: the position means of the cycles' drifts, the command angle
sensor's scale k_as, the +/- pulse mismatch, the digitizer's start offset, the own drift's
wander between positions and the platform's turn (docs/method.md B, D1).

Why here and computed once: the analysis (procedures/drift_pulse/analysis.py) builds these
budgets from its inputs and takes every U it reports from them (U = k(nu_eff) u_c, one rule
with the rate ladder, bench/analysis/coverage.py); result.json, the certificate's annex and
the DCC print the same objects. The azimuth and the horizontal Earth rate combine both
horizontal axes; the two command angle sensors' scales rest on one calibration (one
certificate), so their errors are correlated with r = 1 (GUM 5.2.2, docs/method.md B): a
common scale error leaves the azimuth unchanged and moves the Earth rate in full.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from bench.report.budget import (
    NORMAL,
    RECTANGULAR,
    STUDENT_T,
    Budget,
    Term,
)
from drivers.units import SECONDS_PER_HOUR

DPH = "deg/h"
#: r(k_as,x, k_as,y): both scales from one calibration against one reference, one certificate
#: (docs/method.md B; GUM 5.2.2 with r = 1)
K_AS_CORRELATION = 1.0


@dataclass(frozen=True)
class PositionInput:
    """The cycles at one platform position: their mean drift and its Type A standard
    uncertainty s / sqrt(n) with n - 1 degrees of freedom (docs/method.md D1)."""

    table_deg: float
    mean_dph: float
    ustd_dph: float
    cycles: int


@dataclass(frozen=True)
class CorrectionInput:
    """An instrument correction the analysis applied (issue 58; procedures/drift_pulse/
    corrections.py): `quantity` gain_error_rel or offset_error_v of this gyro's DMM, or
    amplitude_error_rel of the generator; its value and standard uncertainty."""

    where: str
    quantity: str
    value: float
    ustd: float


@dataclass(frozen=True)
class AxisInputs:
    """What one gyro's own and apparent drift are computed from (docs/method.md B):
    own = (k_as,cert / k_as) sum_theta c_theta mean_theta + corrections, with c_theta the
    least-squares weights of the position means (1/2, 1/2 for 0 and 180 deg)."""

    gyro: str
    positions: tuple[PositionInput, ...]
    own_coeffs: tuple[float, ...]
    app_coeffs: tuple[float, ...]
    own_dph: float
    app_dph: float
    k_as_v_per_deg: float
    k_as_u_rel: float
    amplitude_dps: float
    pulse_mismatch_max_rel: float
    angle_mean: float            # int_0^1 G du of the pulse shape
    angle_end: float             # G(1)
    tc_s: float
    offset_s: float
    offset_ustd_s: float
    offset_cycles: int
    random_walk_dph_per_rth: float
    span_h: float
    turn_tolerance_deg: float
    earth_horizontal_dph: float | None   # W_h = 15.041 cos(latitude); None: not given
    vertical: bool = False
    corrections: tuple[CorrectionInput, ...] = ()   # applied (issue 58); none: no rows


def _positions(inp: AxisInputs, coeffs: Sequence[float], prefix: str) -> list[Term]:
    """One Type A input per position mean (Student t, nu = n - 1; docs/method.md D1)."""
    if inp.vertical:
        p = inp.positions[0]
        return [Term(f"{prefix}mean drift of all cycles, w̄ ({p.cycles} cycles; Type A, s/√n)",
                     p.mean_dph, p.ustd_dph, STUDENT_T, coeffs[0], p.cycles - 1, DPH)]
    return [Term(f"{prefix}mean drift at {p.table_deg:g}°, w̄_{p.table_deg:g} ({p.cycles} "
                 "cycles; Type A, s/√n)", p.mean_dph, p.ustd_dph, STUDENT_T, c, p.cycles - 1,
                 DPH) for p, c in zip(inp.positions, coeffs, strict=True)]


def _k_as(inp: AxisInputs, y_dph: float, prefix: str) -> Term:
    """w = -U_int / (k_as Tc^2) (docs/method.md B): dw/dk_as = -w / k_as."""
    return Term(f"{prefix}command angle sensor scale k_as ({inp.gyro}), its calibration",
                inp.k_as_v_per_deg, inp.k_as_v_per_deg * inp.k_as_u_rel, NORMAL,
                -y_dph / inp.k_as_v_per_deg, None, "V/deg")


#: each correction's row text and unit (docs/method.md B, "The drift kind's instrument
#: corrections")
_CORRECTION_ROWS = {
    "gain_error_rel": ("DMM gain correction g applied ({where}), its as-found value "
                       "(Type B, from its calibration's U, k = 2)", "1"),
    "offset_error_v": ("DMM offset correction o applied ({where}), its as-found value "
                       "(Type B, from its calibration's U, k = 2; c = 0: the halves cancel "
                       "it)", "V"),
    "amplitude_error_rel": ("pulse generator amplitude correction a applied ({where}), its "
                            "as-found value (Type B, from its calibration's U, k = 2; c = 0: "
                            "the amplitude drops out)", "1"),
}


def _corrections(inp: AxisInputs, y_dph: float, prefix: str) -> list[Term]:
    """A row per applied correction (docs/method.md B, "The drift kind's instrument
    corrections"): the readings divided by 1 + g give w = w_read / (1 + g), so
    dw/dg = -w / (1 + g); an offset o cancels between the two equal halves of the signed
    integral and the generator's amplitude drops out of w (c = 0: the row shows that the
    correction's u was weighed, and what it weighs)."""
    out = []
    for c in inp.corrections:
        text, unit = _CORRECTION_ROWS[c.quantity]
        sens = -y_dph / (1.0 + c.value) if c.quantity == "gain_error_rel" else 0.0
        out.append(Term(prefix + text.format(where=c.where), c.value, c.ustd, NORMAL, sens,
                        None, unit))
    return out


def _random_walk(inp: AxisInputs, prefix: str) -> Term:
    """The own drift's change between the positions, its random walk over the run's span:
    app = (w_0 - w_180) / 2 takes half of it (docs/method.md B; conservative: the whole span)."""
    return Term(f"{prefix}own-drift change between the positions, Δω_own (random walk "
                f"{inp.random_walk_dph_per_rth:g} °/h/√h over {inp.span_h:.3g} h; its spec)",
                0.0, inp.random_walk_dph_per_rth * math.sqrt(inp.span_h), NORMAL, 0.5, None,
                DPH)


def own_budget(inp: AxisInputs) -> Budget:
    """The own drift's budget (docs/method.md B, D1)."""
    a = abs(inp.amplitude_dps)
    terms = [*_positions(inp, inp.own_coeffs, ""), _k_as(inp, inp.own_dph, ""),
             # an amplitude mismatch eps leaves eps a int_0^1 G du in w, alike at every
             # position: own drift only (docs/method.md B)
             Term("± pulse amplitude mismatch ε (stated bound, uniform)", 0.0,
                  inp.pulse_mismatch_max_rel / math.sqrt(3.0), RECTANGULAR,
                  a * inp.angle_mean * SECONDS_PER_HOUR, None, "1"),
             # a start offset tau leaves 2 a G(1) tau / Tc in w (docs/method.md B); the
             # integration edges sit at the pooled offset, its u remains
             Term(f"digitizer start offset τ (pooled over {inp.offset_cycles} cycles; the "
                  "edges are placed there)", inp.offset_s, inp.offset_ustd_s, NORMAL,
                  2.0 * a * inp.angle_end / inp.tc_s * SECONDS_PER_HOUR,
                  max(inp.offset_cycles - 1, 1), "s"),
             *_corrections(inp, inp.own_dph, "")]
    return Budget(f"own drift ω_own ({inp.gyro})", "own_dph", DPH, inp.own_dph, tuple(terms),
                  note="ω_own = (k_as,cert / k_as) Σ c_θ w̄_θ + control and offset terms "
                       "(docs/method.md B); U = k(ν_eff) u_c (D1)")


def _turn(inp: AxisInputs, prefix: str) -> Term | None:
    """A turn e off 180 deg leaves (the other horizontal component) e / 2 in the apparent
    drift, at most W_h e / 2 (docs/method.md B); e uniform within the stated tolerance."""
    if inp.earth_horizontal_dph is None:
        return None
    return Term(f"{prefix}platform turn off 180°, e (uniform within ±{inp.turn_tolerance_deg:g}°; "
                "c_i at most W_h·π/360)", 0.0, inp.turn_tolerance_deg / math.sqrt(3.0),
                RECTANGULAR, inp.earth_horizontal_dph * math.pi / 360.0, None, "deg")


def apparent_budget(inp: AxisInputs) -> Budget | None:
    """The apparent drift's budget; None for a vertical gyro (its apparent drift is
    15.041 sin(latitude), computed, not measured)."""
    if inp.vertical:
        return None
    terms = [*_positions(inp, inp.app_coeffs, ""), _k_as(inp, inp.app_dph, ""),
             _random_walk(inp, "")]
    turn = _turn(inp, "")
    if turn is not None:
        terms.append(turn)
    terms += _corrections(inp, inp.app_dph, "")
    return Budget(f"apparent drift ω_app at 0° ({inp.gyro})", "apparent_dph", DPH,
                  inp.app_dph, tuple(terms),
                  note="ω_app = (k_as,cert / k_as) Σ c_θ w̄_θ (docs/method.md B); "
                       "U = k(ν_eff) u_c (D1)")


def _through_apparent(inp: AxisInputs, scale: float) -> list[Term]:
    """The axis's apparent-drift inputs (not its turn) with c_i times d(result)/d(app)."""
    terms = [*_positions(inp, inp.app_coeffs, f"{inp.gyro.upper()}: "),
             _k_as(inp, inp.app_dph, f"{inp.gyro.upper()}: "),
             _random_walk(inp, f"{inp.gyro.upper()}: "),
             *_corrections(inp, inp.app_dph, f"{inp.gyro.upper()}: ")]
    return [Term(t.quantity, t.estimate, t.ustd, t.distribution, t.sensitivity * scale,
                 t.dof, t.unit) for t in terms]


def _two_axes(x: AxisInputs, y: AxisInputs, dx: float, dy: float
              ) -> tuple[list[Term], tuple[tuple[int, int, float], ...]]:
    """Both axes' inputs through d(result)/d(app_x) = dx, d(result)/d(app_y) = dy, and the
    correlation of the two k_as (one certificate, r = 1; GUM 5.2.2, docs/method.md B)."""
    tx, ty = _through_apparent(x, dx), _through_apparent(y, dy)
    i = len(x.positions)                  # k_as follows the position means
    return [*tx, *ty], ((i, len(tx) + len(y.positions), K_AS_CORRELATION),)


def azimuth_budget(x: AxisInputs, y: AxisInputs, azimuth_deg: float) -> Budget:
    """A = atan2(-app_y, app_x) (docs/method.md B): dA/dapp_x = app_y / r^2,
    dA/dapp_y = -app_x / r^2 (rad per deg/h), r^2 = app_x^2 + app_y^2; the one turn of the
    platform rotates both apparent drifts, A by e / 2 (c = 1/2)."""
    r2 = x.app_dph ** 2 + y.app_dph ** 2
    deg = 180.0 / math.pi
    terms, corr = _two_axes(x, y, deg * y.app_dph / r2, -deg * x.app_dph / r2)
    turn = _turn(x, "")
    if turn is not None:
        terms.append(Term("platform turn off 180°, e (one turn for both axes; uniform "
                          f"within ±{x.turn_tolerance_deg:g}°)", 0.0, turn.ustd, RECTANGULAR,
                          0.5, None, "deg"))
    return Budget("platform azimuth A", "azimuth_deg", "deg", azimuth_deg, tuple(terms),
                  correlations=corr, note="r(k_as x, k_as y) = 1: one calibration certificate for both sensors' "
                       "scale (GUM 5.2.2, docs/method.md B); a common scale error does not "
                       "turn A, so the two k_as contributions cancel")


def earth_budget(x: AxisInputs, y: AxisInputs, w_h_dph: float) -> Budget:
    """W_h = sqrt(app_x^2 + app_y^2) (docs/method.md B): dW/dapp = app / W_h; the turn
    rotates (app_x, app_y) and leaves W_h unchanged to first order."""
    terms, corr = _two_axes(x, y, x.app_dph / w_h_dph, y.app_dph / w_h_dph)
    return Budget("horizontal Earth rate W_h from the apparent drifts", "earth_horizontal_dph",
                  DPH, w_h_dph, tuple(terms), correlations=corr,
                  note="r(k_as x, k_as y) = 1: one calibration certificate for both sensors' "
                       "scale (GUM 5.2.2, docs/method.md B); a common scale error scales "
                       "W_h in full. The platform's turn rotates (app_x, app_y): it leaves "
                       "W_h unchanged to first order and is not an input here")
