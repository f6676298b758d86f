"""The method statements printed on the certificate (docs/method.md parts A and B, restated).

Kept as data beside the builder so a reviewer can read the certificate's wording in one
place. Formulas use plain Unicode that both the HTML and the PDF font (DejaVu) carry.
"""

from __future__ import annotations

from bench.certificate.model import Para

A_REFERENCE = ("Intra-turn rate instability of a rate-table axis by the fixed-angle method with "
               "a zero-mark sensor, a frequency counter and a fibre-optic gyro (FOG) "
               "cross-calibrated against the counter (docs/method.md part A; seed paper 000).")

A_TEXT: tuple[Para, ...] = (
    Para(A_REFERENCE),
    Para("Measuring chain. An optical slot sensor on the base gives one pulse per revolution "
         "(the zero mark); a frequency counter times the period T between zero marks; a FOG on "
         "the table top streams the instantaneous rate. The counter sees only |T|: the sign of "
         "the per-turn rate is the sign of the commanded rate."),
    Para("A1 Per-turn rate (fixed-angle method), one value per revolution i:", "strong"),
    Para("ω_i = 360° / T_i", "formula"),
    Para("Timing of one zero-mark edge (standard uncertainty), of one period (two independent "
         "edges) and the per-turn rate error it causes:", "body"),
    Para("Δ_edge = √(Δ_counter² + Δ_trigger²);   ΔT = √2 · Δ_edge;   Δω/ω ≈ ΔT / T",
         "formula"),
    Para("The source paper's ΔT = √(Δ_counter² + Δ_trigger²) is written per edge here; a "
         "period has two edges. The timing floor of σ printed with the results is ΔT / T, "
         "T the mean period: the σ that edge timing alone would give.", "note"),
    Para("A2 Per-turn rate error and instability over N turns at the commanded rate ω_set:",
         "strong"),
    Para("δ = (mean(ω_i) − ω_set) / ω_set     (eq. 1, signed; computed exactly so)",
         "formula"),
    Para("Sign convention: ω_set and ω_i carry the sign of the direction, so δ > 0 means the "
         "table turns faster than commanded in either direction and δ < 0 slower. The source "
         "paper's eq. 1 is |mean − ω_set| / |ω_set|, which is |δ|; the conformity checks "
         "compare |δ| with the tolerance. mean(ω_i) is the mean over whole turns, N·360° / "
         "(t_N − t_0).", "note"),
    Para("σ = √( Σ (ω_i − mean(ω))² / (N − 1) ) / |mean(ω)|     (eq. 2)", "formula"),
    Para("U of δ (k = 2) combines the timing of each window's two end edges, the counter's "
         "timebase (rectangular) and the turn-to-turn repeatability, a Type A term widened "
         "for few turns by the small-sample factor of GUM Supplement 1, 6.4.9:", "body"),
    Para("u_rep = σ / √N · √((N − 1) / (N − 3))  for N > 3  (t₀.₉₇₅(N − 1) / 2 for N ≤ 3);   "
         "U = 2·√(u_timing² + u_timebase² + u_rep²)", "formula"),
    Para("Note on eq. 2: the source paper prints eq. 2 without the square root (a variance "
         "divided by the mean, which has units of °/s). This certificate uses the relative "
         "standard deviation above, which is what the paper's numbers and its text describe.",
         "note"),
    Para("A3 Cross-calibration of the FOG against the counter for each ± pair of rates "
         "(ω+ = −ω−); FOG model ω_fog = k·ω_true + ω0, with FOG means taken over exactly "
         "the turns the counter timed:", "strong"),
    Para("k = (Ω_fog+ − Ω_fog−) / (Ω_cnt+ − Ω_cnt−)   (eq. 5);   "
         "ω0 = Ω_fog+ − k·Ω_cnt+   (eq. 6);   ω_true(t) = (ω_fog(t) − ω0) / k", "formula"),
    Para("A4 Systematic intra-turn component: every FOG sample is given its table angle φ "
         "from the zero-mark timestamps and the integrated calibrated rate (angle domain), "
         "and the harmonic model Δω_sys(φ) = ω_set·Σ a_h cos(hφ + p_h), h = 1…H, plus a "
         "mains-frequency tone in time, is fitted by linear least squares; amplitude and phase "
         "are reported with their uncertainties. The paper's binned average by angle is kept "
         "for comparison in the plots.", "body"),
    Para("A5 Random component and intra-turn instability:", "strong"),
    Para("Δω_rand = ω_true − Δω_sys(φ) − ω_set;   intra-turn instability = std(Δω_rand) / "
         "|ω_set|", "formula"),
    Para("It is reported at the FOG's output bandwidth (raw), with the FOG's own noise floor "
         "removed in quadrature (floor-corrected), and for the random part averaged over "
         "1°, 10° and 360° of table angle, so it can be read against a rate-table "
         "datasheet.", "body"),
)

A_IMPROVEMENTS: tuple[str, ...] = (
    "Angle assignment from zero-mark timestamps and the integrated calibrated rate, instead of "
    "the paper's sample index × ω_set / f mapping (which accumulates error when the table's "
    "rate is off).",
    "Least-squares fit of harmonics 1…H in angle and of the mains tone in time, with "
    "uncertainties, in place of the binned average alone.",
    "The FOG's noise floor (from a record at rest or from the pair's own data) is removed in "
    "quadrature; the raw figure is printed beside the corrected one.",
    "Intra-turn instability is also given averaged over 1°, 10° and 360°.",
)

SEQUENCE_TEXT = {
    "+-+": "Halves of each pair run in the symmetric order +ω, −ω, +ω (the + turns split "
           "around the − half), so a linear FOG bias drift cancels in k and ω0; the paper ran "
           "+ω then −ω.",
    "+-": "Halves of each pair run in the paper's order +ω then −ω; a FOG bias drift during the "
          "pair enters k and ω0 and is part of their uncertainty.",
}

B_REFERENCE = ("Own and apparent drift of a gyro-stabilised platform by alternating-sign "
               "controlled precession, and the platform azimuth from two horizontal axes "
               "(docs/method.md part B; seed paper 004).")

B_TEXT: tuple[Para, ...] = (
    Para(B_REFERENCE),
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

STATEMENTS: tuple[str, ...] = (
    "The results relate only to the item calibrated, as identified in section 1, at the "
    "conditions stated.",
    "The expanded uncertainties U are the standard uncertainties multiplied by the coverage "
    "factor k = 2, which for a normal distribution gives a coverage probability of about 95 %. "
    "U is printed with at most two significant digits and the value is rounded to the same "
    "decimal place (GUM 7.2.6; EA-4/02).",
    "Relative values are fractions of the commanded rate, printed in % or in ppm "
    "(1 ppm = 0.0001 %) as the column header states.",
    "This certificate shall not be reproduced except in full without the written approval of "
    "the issuing laboratory.",
)
