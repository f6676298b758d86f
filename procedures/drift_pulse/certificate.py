"""The drift procedure's part of its calibration certificate (docs/method.md part B).

The certificate (bench/app/certificate/build.py) asks the kind for these through
`CertificateParts`: the platform under test as the item, the method statement, the
digitizer's start offset as a deviation, and the results: own and apparent drift per
axis, the azimuth, the drift per position and cycle, the budget and the plots.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from bench.analysis.coverage import DOF_INFINITE
from bench.report.budget import Budget
from bench.report.certificate import methods
from bench.report.certificate.model import Block, Fields, Para, Section, Table
from bench.report.certificate.parts import (
    NOT_RECORDED,
    CertificateParts,
    Sources,
    figure_of,
    stand_of,
    text_of,
    vu_text,
)
from bench.report.certificate.rounding import format_sig, format_value_u
from bench.report.result_frame import Check
from procedures.drift_pulse import plots
from procedures.drift_pulse.codec import drift_model
from procedures.drift_pulse.result import AxisFigures, DriftFigures

# -- the method statement (docs/method.md part B, restated) ---------------------------------

B_TEXT: tuple[Para, ...] = (
    Para(methods.B_REFERENCE),
    Para("A torque sensor applies a control pulse of duration Tc, then the same pulse with "
         "opposite sign; the command angle sensor gives U(t) = k_as·α(t). An integrator adds U "
         "during the first pulse and subtracts it during the second:", "body"),
    Para("U_int = ∫₀^Tc U dt − ∫_Tc^2Tc U dt = −k_as·ω·Tc²,    ω = −U_int / (k_as·Tc²)",
         "formula"),
    Para("For any pulse shape symmetric in time the torque-sensor scale, the angular momentum "
         "and the pulse amplitude drop out; for a non-symmetric shape the control term "
         "2∫A dt − A(Tc)·Tc is computed and removed. Samples lie on the pulse edges and the "
         "integral uses the trapezoid rule (a half-sample offset would leave a control residue "
         "of about amplitude / (fs·Tc)).", "body"),
    Para("The platform is turned by 180° about the vertical and the cycles repeated: the "
         "apparent drift changes sign, the own drift does not:", "body"),
    Para("ω_own = (ω_0 + ω_180) / 2,   ω_app = (ω_0 − ω_180) / 2", "formula"),
    Para("Apparent drift of a horizontal axis whose input axis points at azimuth ψ: "
         "Ω_h·cos ψ with Ω_h = 15.041 °/h · cos(latitude). With the X input axis at azimuth A "
         "and Y at A + 90°: app_x = Ω_h cos A, app_y = −Ω_h sin A, A = atan2(−app_y, app_x).",
         "body"),
)

# -- what the certificate asks ---------------------------------------------------------------

class DriftCertificate(CertificateParts):
    """The drift procedure's answers to the certificate (its DCC: procedures/
    drift_pulse/dcc.py, the kind's `dcc` part)."""

    certificate_procedure_name = "drift by alternating-sign pulses (docs/method.md part B)"
    certificate_procedure_id = ("RB-DP", "B", methods.PAPER_B)
    certificate_measured = (("own_drift", "own drift"), ("apparent_drift", "apparent drift"),
                            ("azimuth", "platform azimuth"))
    certificate_quantities = {
        "own_drift": "own drift",
        "apparent_drift": "apparent drift",
        "earth_horizontal_rate": "horizontal Earth rate",
        "azimuth": "platform azimuth",
    }

    def certificate_recognises(self, src: Sources) -> bool:
        return bool(src.frame.part("drift"))

    def certificate_item(self, src: Sources) -> tuple[str, str]:
        """The platform under test and its gyros (the stand is the laboratory's)."""
        plat = src.stand_file.get("platform", {}) or {}
        ident = plat.get("identity", {}) or {}
        if not ident:
            return ("gyro platform (identity not given in the stand file's "
                    "platform.identity)", NOT_RECORDED)
        gyros = plat.get("gyros", {}) or {}
        names = "; ".join(
            f"{g}: " + ", ".join(
                str(v) for v in (spec.get("model"), spec.get("serial") and
                                 f"serial {spec['serial']}") if v)
            if isinstance(spec, Mapping) and (spec.get("model") or spec.get("serial"))
            else f"{g}: serial not given in the stand file"
            for g, spec in gyros.items())
        text = f"{text_of(ident.get('maker'))} {text_of(ident.get('model'))}"
        if names:
            text += f", with its gyros ({names})"
        return text, text_of(ident.get("serial"))

    def certificate_identification(self, src: Sources) -> Sequence[tuple[str, str]]:
        stand = stand_of(src)
        return [("Test stand used", f"{text_of(stand.maker)} {text_of(stand.model)}, "
                                    f"serial {text_of(stand.serial)}")]

    def certificate_method(self, src: Sources) -> Sequence[Block]:
        return B_TEXT

    def certificate_run_deviations(self, src: Sources) -> Sequence[str]:
        run = []
        for axis, ax in src.model(drift_model).axes.items():
            off = ax.start_offset
            if off.detected:
                shift = format_value_u(off.offset_s, off.offset_U_s, 1e3,
                                       signed=True).joined("ms")
                run.append(f"Axis {axis}: the digitizer's samples were {shift} "
                           "off the pulse edges; the integration edges were placed where the "
                           "pulses are (docs/method.md B: a half-sample offset would bias the "
                           "drift).")
        return run

    def certificate_sections(self, src: Sources, number: str,
                             checks: Sequence[Check]) -> list[Section]:
        return _drift_results(src.model(drift_model), number)

    def certificate_statements(self, statements: Sequence[str]) -> list[str]:
        """No relative values here: the drift is in °/h."""
        return [t for t in statements if not t.startswith("Relative values")]


# -- the results -----------------------------------------------------------------------------

def _k_text(budget: Budget | None) -> str:
    """'k = 2.09 (ν_eff = 29.8)' of a figure's budget (docs/method.md D1), the k and nu_eff its
    U was computed with (procedures/drift_pulse/budgets.py); '—' when no budget says."""
    if budget is None:
        return "—"
    nu = budget.dof_eff
    return f"{budget.k:.2f} ({'∞' if nu is None or nu > DOF_INFINITE else f'{nu:.1f}'})"


def _drift_results(drift: DriftFigures, number: str) -> list[Section]:
    """The results section: how U is stated, the own and apparent drift per axis, the
    site and the platform's azimuth and Earth rate, the drift per position and cycle, and
    their plots (docs/method.md B)."""
    axes = drift.axes
    budgeted = any(ax.budgets for ax in axes.values())
    blocks: list[Block] = [Para(
        "Drift in °/h; each value followed by its expanded uncertainty U for about 95 %: "
        "U = k·u_c of its budget in the annex, k = t_95.45(ν_eff) (docs/method.md D1, the one "
        "rule of every U on this certificate)." if budgeted else
        "Drift in °/h; each value followed by its expanded uncertainty U for about 95 %, as "
        "result.json states it (it carries no budget).")]
    if axes:
        blocks.append(_drift_table(axes, budgeted))
    fields = _platform_fields(drift)
    if fields:
        blocks.append(Fields(tuple(fields)))
    positions = _positions_table(axes)
    if positions is not None:
        blocks.append(positions)
    blocks += figure_of("Drift estimate per cycle, by axis and platform position",
                        plots.drift_cycles, axes)
    for axis, ax in axes.items():
        if ax.example_cycle is not None:
            blocks += figure_of(f"Axis {axis}: U(t) and the integrator output over one cycle",
                                plots.drift_cycle, axis, ax.example_cycle)
    return [Section(number, "Results", tuple(blocks))]


def _drift_table(axes: Mapping[str, AxisFigures], budgeted: bool) -> Table:
    """Own and apparent drift per axis with U (and k, ν_eff when budgeted), beside the own
    drift at nominal edges, for comparison with the paper's integrator."""
    has_nominal = bool(axes)
    rows = []
    for axis, ax in axes.items():
        row = [axis, vu_text(ax.own_dph, ax.own_U_dph, signed=True),
               vu_text(ax.apparent_dph, ax.apparent_U_dph, signed=True),
               text_of(len(ax.cycles) or None)]
        if budgeted:
            row.insert(2, _k_text(ax.own_budget))
            row.insert(4, _k_text(ax.apparent_budget))
        if has_nominal:
            row.insert(len(row) - 1, format_sig(ax.own_nominal_edges_dph, 4, signed=True))
        rows.append(tuple(row))
    header = ["Axis", "Own drift ± U, °/h", "Apparent drift at 0° ± U, °/h", "Cycles"]
    widths = [0.6, 1.9, 2.1, 0.7]
    if budgeted:
        header.insert(2, "k (ν_eff)")
        header.insert(4, "k (ν_eff)")
        widths.insert(2, 1.0)
        widths.insert(4, 1.0)
    notes = []
    if has_nominal:
        header.insert(len(header) - 1, "Own drift at nominal edges, °/h")
        widths.insert(len(widths) - 1, 1.6)
        notes.append("Own drift at nominal edges: the same cycles integrated with the "
                     "pulse edges at the digitizer's nominal sample times, as the paper's "
                     "integrator does; shown for comparison only.")
    return Table(tuple(header), tuple(rows), widths=tuple(widths),
                 align="l" + "r" * (len(header) - 1),
                 caption="Own and apparent drift per axis (docs/method.md B)",
                 notes=tuple(notes))


def _platform_fields(drift: DriftFigures) -> list[tuple[str, str]]:
    """The site latitude, and the platform's azimuth and horizontal Earth rate from the
    apparent drifts, against the Earth rate expected there."""
    fields: list[tuple[str, str]] = []
    if drift.latitude_deg is not None:
        fields.append(("Site latitude", f"{drift.latitude_deg:g}°"))
    plat = drift.platform
    if plat is not None:
        k = _k_text(drift.azimuth_budget)
        fields.append(("Platform azimuth (X input axis) ± U",
                       vu_text(plat.azimuth_deg, plat.azimuth_U_deg) + " °"
                       + ("" if k == "—" else f"; k (ν_eff) = {k}")))
        fields.append(("U of the azimuth", format_value_u(plat.azimuth_U_deg * 60, None,
                                                          sig_without_u=2).joined("arcmin")))
        text = vu_text(plat.earth_horizontal_dph, plat.earth_horizontal_U_dph) + " °/h"
        if (k := _k_text(drift.earth_budget)) != "—":
            text += f" (k (ν_eff) = {k})"
        if drift.earth_horizontal_expected_dph is not None:
            text += (f"; expected 15.041·cos(latitude) = "
                     f"{drift.earth_horizontal_expected_dph:.4f} °/h"
                     + (", consistent" if plat.earth_horizontal_consistent
                        else ", NOT consistent"))
        fields.append(("Horizontal Earth rate from the apparent drifts", text))
    return fields


def _positions_table(axes: Mapping[str, AxisFigures]) -> Table | None:
    """The drift per platform position (mean, spread, u of the mean) and per cycle."""
    prow = []
    for axis, ax in axes.items():
        for p in ax.positions:
            n = p.cycles
            # the mean's Type A standard uncertainty s/sqrt(n), nu = n - 1 (docs/method.md D1):
            # a budget input, stated without a U of its own (D2)
            prow.append((axis, f"{p.table_deg:g}", str(n),
                         format_sig(p.mean_dph, 5, signed=True), format_sig(p.std_dph, 2),
                         format_sig(p.mean_ustd_dph, 2), str(n - 1) if n > 1 else "—",
                         ", ".join(format_sig(x, 5, signed=True) for x in p.drifts_dph)))
    if not prow:
        return None
    return Table(("Axis", "Position, °", "Cycles", "Mean w̄, °/h", "Std s, °/h",
                  "u(w̄) = s/√n, °/h", "ν", "Drift per cycle, °/h, in order"),
                 tuple(prow), widths=(0.5, 0.7, 0.5, 1.1, 0.8, 1.0, 0.4, 3.6),
                 align="lrrrrrrl",
                 caption="Drift per platform position and per cycle",
                 notes=("The position means are inputs of the own and apparent "
                        "drifts' budgets (annex): each with its standard "
                        "uncertainty and degrees of freedom, no U of its own "
                        "(docs/method.md D1, D2).",))
