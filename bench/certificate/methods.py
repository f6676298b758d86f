"""The wording the certificate and the DCC share: each part's reference line and the
closing statements.

Each procedure's method statement is its own (procedures/*/certificate.py, asked for by
the certificate). Formulas use plain Unicode that both the HTML and the PDF font (DejaVu)
carry.
"""

from __future__ import annotations

A_REFERENCE = ("Intra-turn rate instability of a rate-table axis by the fixed-angle method with "
               "a zero-mark sensor, a frequency counter and a fibre-optic gyro (FOG) "
               "cross-calibrated against the counter (docs/method.md part A; seed paper 000).")

B_REFERENCE = ("Own and apparent drift of a gyro-stabilised platform by alternating-sign "
               "controlled precession, and the platform azimuth from two horizontal axes "
               "(docs/method.md part B; seed paper 004).")

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
