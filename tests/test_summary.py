"""The console summary rounds as the certificate does (hand-written result, hand-rounded)."""

from __future__ import annotations

from bench.summary import summary_lines

RESULT = {
    "verdict": "pass",
    "axes": {"inner": {
        "rates": [{"set_rate_dps": 20.0, "turns": 4, "rate_error_rel": -2.1137e-7,
                   "rate_error_u_rel": 3.0e-8, "rate_instability_rel": 1.7e-8,
                   "intra_turn_instability_rel": 5.0e-4,
                   "intra_turn_instability_corrected_rel": None, "verdict": "pass"}],
        "pairs": [{"rate_dps": 20.0, "k": 0.99949853, "k_u": 2.74e-6,
                   "w0_dps": -0.0025612, "w0_u_dps": 5.31e-5}]}},
    "drift": {"axes": {"x": {"own_dph": 0.348281, "own_u_dph": 0.00214,
                             "apparent_dph": 0.893551, "apparent_u_dph": 0.0019}},
              "azimuth_deg": 79.99777, "azimuth_u_deg": 0.02114},
}


def test_summary_rounds_u_to_two_digits_and_the_value_to_match() -> None:
    text = "\n".join(summary_lines(RESULT))
    # -0.21137 ppm +/- 0.030 ppm: U keeps its trailing zero, the value its third decimal
    assert "\u22120.211 ± 0.030" in text
    assert "0.017" in text and "0.050 %" in text
    assert "k = 0.9994985 ± 0.0000027" in text
    assert "w0 = \u22120.002561 ± 0.000053 deg/s" in text
    assert "own drift +0.3483 ± 0.0021 deg/h, apparent +0.8936 ± 0.0019 deg/h" in text
    assert "azimuth 79.998 ± 0.021 deg" in text
    assert text.splitlines()[-1] == "verdict: PASS"
    row = next(line for line in text.splitlines() if line.startswith("inner") and "PASS" in line)
    assert row.split()[-2] == "-"      # no corrected figure: a dash, not a blank
