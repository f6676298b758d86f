"""The wording the certificate and the DCC share: each part's reference line and the
closing statements.

Each procedure's method statement is its own (procedures/*/certificate.py, asked for by
the certificate). Formulas use plain Unicode that both the HTML and the PDF font (DejaVu)
carry.
"""

from __future__ import annotations

#: the source papers, as bibliographic references (docs/method.md parts A and B)
PAPER_A = ("Lazarev V. A., Ivanov P. A., Uskov A. D. Method for assessing intra-turn "
           "instability of rotation speed of a simulation stand axes. Journal of Instrument "
           "Engineering (Izvestiya vysshikh uchebnykh zavedenii. Priborostroenie), 2025, "
           "vol. 68, no. 1, pp. 67-78 (in Russian). DOI: 10.17586/0021-3454-2025-68-1-67-78.")
PAPER_B = ("Alternating-sign pulse method of measuring the drift rate of gyroscopic devices "
           "during controlled precession (in Russian). Authors, journal and year are not "
           "stated in the copy the project holds (METHOD.md, seed 004_99d89a9903540a42).")

A_REFERENCE = ("Intra-turn rate instability of a rate-table axis by the fixed-angle method with "
               "a zero-mark sensor, a frequency counter and a fibre-optic gyro (FOG) "
               "cross-calibrated against the counter (docs/method.md part A, after [A]).")

B_REFERENCE = ("Own and apparent drift of a gyro-stabilised platform by alternating-sign "
               "controlled precession, and the platform azimuth from two horizontal axes "
               "(docs/method.md part B, after [B]).")

VALIDATION = ("Non-standard method (ISO/IEC 17025 7.2.2). Its implementation in this "
              "software release is checked against known truth: the simulated stand's twins "
              "(every reported interval against the twin's truth over many seeds), the "
              "source paper's check values, and hand-derived values (the project's test "
              "suite and benchmark campaigns for this release). No comparison with a "
              "physical reference artefact is recorded here.")

STATEMENTS: tuple[str, ...] = (
    "The results relate only to the item calibrated, as identified in section 1, at the "
    "conditions stated.",
    "The expanded uncertainties U are the combined standard uncertainties multiplied by the "
    "coverage factor k = t_95.45(ν_eff), the Student t factor of the effective degrees of "
    "freedom (EA-4/02 M:2022 annex E): k = 2 where ν_eff is infinite or large, as stated in "
    "each budget of the annex otherwise, for a coverage probability of about 95 %. A "
    "quantity whose distribution is not symmetric is given with its coverage interval "
    "[lower, upper], or as a one-sided limit '< L' (docs/method.md D1, D2). U is printed with at most two significant digits and the value is rounded to the same "
    "decimal place (GUM 7.2.6; EA-4/02).",
    "Relative values are fractions of the commanded rate, printed in % or in ppm "
    "(1 ppm = 0.0001 %) as the column header states.",
    "This certificate shall not be reproduced except in full without the written approval of "
    "the issuing laboratory.",
)
