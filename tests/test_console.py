"""The console's parts against hand-derived truth: the wall-time estimate, the times as
printed, the summary's alignment, the JSON log, the operator-prompt record."""

from __future__ import annotations

import io
import json

import pytest

from bench.app.certificate.operator import prompt_blocks, software_note
from bench.app.console import JsonConsole, PlainConsole, QuietConsole, Timeline, format_eta
from bench.app.console.report import table_lines
from bench.app.console.timeline import fit_step_cost
from bench.app.summary import summarize
from bench.core.events import decode_all
from bench.core.plan import Step
from bench.core.progress import RELATIVE, Figure
from bench.report.certificate.model import Document, Fields, Section, Table


class Clocks:
    """A bench clock and a wall clock the test moves by hand (no real time involved)."""

    def __init__(self) -> None:
        self.bench_s = 0.0
        self.wall_s = 0.0

    def spend(self, bench_s: float, wall_s: float) -> None:
        self.bench_s += bench_s
        self.wall_s += wall_s


def test_fit_recovers_a_known_step_cost_line() -> None:
    # wall = 0.01 s per bench s (100x) + 0.05 s per step, exactly
    est = [0.0, 30.0, 72.0, 2.5, 144.0]
    a, b = fit_step_cost(est, [0.01 * e + 0.05 for e in est])
    assert a == pytest.approx(0.01, rel=1e-9) and b == pytest.approx(0.05, rel=1e-9)
    # a first step alone that took no bench time: all of it is per-step cost
    assert fit_step_cost([0.0], [0.2]) == (0.0, 0.2)
    assert fit_step_cost([], []) is None


def test_wall_left_is_measured_not_the_configured_speed() -> None:
    """The clock runs at 50x; each step also costs 0.1 s the plan does not count. After
    two steps the estimate is the truth: the rest at 50x plus 0.1 s a step."""
    c = Clocks()
    est = [10.0, 20.0, 0.0, 30.0]
    tl = Timeline(est, lambda: c.bench_s, lambda: c.wall_s)
    for i in (0, 1):
        tl.start(i)
        c.spend(est[i], est[i] / 50 + 0.1)
        tl.finish(i)
    tl.start(2)
    eta = tl.now()
    assert eta.bench_left_s == pytest.approx(30.0)
    assert eta.wall_left_s == pytest.approx((0 / 50 + 0.1) + (30 / 50 + 0.1))
    assert eta.speed == pytest.approx(30.0 / 0.8)
    assert eta.done_fraction == pytest.approx(0.5)
    # half-way through the last step, half of its cost is left
    c.spend(0.0, 0.1)
    tl.finish(2)
    tl.start(3)
    c.spend(15.0, 0.35)
    eta = tl.now()
    assert eta.bench_left_s == pytest.approx(15.0)
    assert eta.wall_left_s == pytest.approx(0.7 - 0.35)
    assert eta.step_fraction == pytest.approx(0.5)


def test_work_beside_the_steps_is_a_floor_under_the_wall_estimate() -> None:
    """A pair's analysis still running in the worker (2 s owed) outlasts the last step's
    0.2 s: the run ends when both are done."""
    c = Clocks()
    owed = [0.0]
    tl = Timeline([30.0, 30.0], lambda: c.bench_s, lambda: c.wall_s, backlog_s=lambda: owed[0])
    tl.start(0)
    c.spend(30.0, 0.2)
    tl.finish(0)
    tl.start(1)
    assert tl.now().wall_left_s == pytest.approx(0.2)
    owed[0] = 2.0
    assert tl.now().wall_left_s == pytest.approx(2.0)


def test_no_wall_estimate_before_a_step_with_bench_time_was_timed() -> None:
    c = Clocks()
    tl = Timeline([0.0, 30.0], lambda: c.bench_s, lambda: c.wall_s)
    tl.start(0)
    c.spend(0.0, 0.01)
    tl.finish(0)
    tl.start(1)
    assert tl.now().wall_left_s is None and tl.now().wall_text() == "measuring"


@pytest.mark.parametrize("seconds, text", [(0.0, "0.0 s"), (0.03, "< 0.1 s"), (0.44, "0.4 s"),
                                           (9.96, "10 s"), (59.4, "59 s"), (75, "1 min 15 s"),
                                           (None, "measuring")])
def test_times_left_as_printed(seconds: float | None, text: str) -> None:
    assert format_eta(seconds) == text


def _doc() -> Document:
    per_turn = Table(("Set rate, °/s", "Turns", "Mean rate ± U, °/s", "Rate error δ ± U, ppm",
                      "Instability σ ± U, ppm", "Timing floor of σ, ppm", "Verdict"),
                     (("+10", "4", "+9.9999990 ± 0.0000012", "−0.10 ± 0.12", "0.069 ± 0.056",
                       "0.002", "PASS"),
                      ("−200", "4", "−199.99998 ± 0.00001", "−0.064 ± 0.027", "0.015 ± 0.012",
                       "0.0004", "FAIL (guard band)")),
                     align="rcrrrrc", caption="Axis outer: per-turn rate error and instability")
    intra = Table(("Set rate, °/s", "Raw ± U, %", "FOG floor, %", "Floor-corrected, %"),
                  (("+10", "0.10021 ± 0.00037", "0.1", "< 0.018 (not resolved)"),
                   ("−200", "0.004978 ± 0.000083", "0.005", "0.0012 (≤ 0.0020)")),
                  align="rrrr", caption="Axis outer: intra-turn instability")
    pairs = Table(("Pair, °/s", "k ± U", "ω0 ± U, °/s", "ω0 ± U, °/h"),
                  (("±10", "1.0002925 ± 0.0000038", "+0.002066 ± 0.000037", "+7.44 ± 0.13"),),
                  align="rrrr", caption="Axis outer: FOG cross-calibration per ± pair")
    ident = Fields((("Statement of conformity", "FAIL: 1 of 2 checks did not meet ..."),))
    return Document("RT-1", "Calibration certificate", "", "lab", "2026-11-22", "fail",
                    (Section("1", "Identification", (ident,)),
                     Section("6.1", "Axis outer", (per_turn, intra, pairs))), "")


def test_summary_is_the_certificates_cells_aligned_under_their_headers() -> None:
    s = summarize(_doc(), {"procedure": "rate-ladder"})
    ladder, pair = s.tables
    assert ladder.header == ("Set rate, °/s", "Turns", "Rate error δ ± U, ppm",
                             "Instability σ ± U, ppm", "Intra-turn raw ± U, %",
                             "Floor-corrected, %", "Verdict")
    assert ladder.rows[1] == ("−200", "4", "−0.064 ± 0.027", "0.015 ± 0.012",
                              "0.004978 ± 0.000083", "0.0012 (≤ 0.0020)", "FAIL (guard band)")
    assert ladder.rows[0][5] == "< 0.018 (not resolved)"
    assert pair.rows == (("±10", "1.0002925 ± 0.0000038", "+0.002066 ± 0.000037"),)
    assert s.verdict == "FAIL" and s.statement.startswith("FAIL: 1 of 2")
    lines = table_lines(ladder)
    head, rows = lines[1], lines[3:]
    # right-aligned columns end where their header ends; the rule is as wide as the header
    for name in ("Rate error δ ± U, ppm", "Intra-turn raw ± U, %", "Floor-corrected, %"):
        end = head.index(name) + len(name)
        for row, cells in zip(rows, ladder.rows, strict=True):
            cell = cells[ladder.header.index(name)]
            assert row[end - len(cell):end] == cell, (name, row)
    assert set(lines[2]) == {"-"} and len(lines[2]) == len(head)


def test_plain_summary_is_uncoloured_and_quiet_prints_only_the_verdict() -> None:
    err, out = io.StringIO(), io.StringIO()
    PlainConsole(err, out=out).summary(summarize(_doc(), {"procedure": "rate-ladder"}))
    assert "\x1b[" not in out.getvalue() and out.getvalue().splitlines()[-1] == "verdict: FAIL"
    out = io.StringIO()
    quiet = QuietConsole(err, out=out)
    quiet.line("wrote x")
    quiet.warn("WARNING lost samples")
    quiet.summary(summarize(_doc(), {"procedure": "rate-ladder"}))
    assert out.getvalue() == "verdict: FAIL\n" and err.getvalue() == "WARNING lost samples\n"


def test_json_log_is_one_object_per_line() -> None:
    c = Clocks()
    steps = [Step("static", "outer", "FOG at rest", 30.0), Step("stop", "outer", "stop", 1.0)]
    stream = io.StringIO()
    con = JsonConsole(stream, out=io.StringIO())
    con.begin(steps, lambda: c.bench_s)
    con.step(0)
    con.reading("FOG mean", "outer at rest", Figure("", 0.0019987, unit="°/s", signed=True))
    con.warn("  WARNING x")
    con.result("outer ±10 deg/s", Figure("k", 1.00029253, 3.8e-6))
    con.summary(summarize(_doc(), {"procedure": "rate-ladder"}))
    recs = [json.loads(line) for line in stream.getvalue().splitlines()]
    assert [r["event"] for r in recs] == ["plan", "step", "reading", "warning", "result",
                                          "summary"]
    assert recs[0]["bench_estimate_s"] == 31.0
    assert recs[1]["index"] == 1 and recs[1]["bench_left_s"] == 31.0
    assert recs[2]["text"] == "+0.001999 °/s" and recs[2]["figures"][0]["value"] == 0.0019987
    assert recs[4]["figures"][0] == {"name": "k", "value": 1.00029253, "u": 3.8e-6, "unit": "",
                                     "text": "1.0002925 ± 0.0000038"}
    assert recs[5]["verdict"] == "FAIL"
    assert recs[5]["tables"][0]["rows"][0][5] == "< 0.018 (not resolved)"


def test_figures_are_rounded_as_the_certificate_rounds() -> None:
    """Hand-rounded: U to two significant digits and the value to its decimal; fractions
    of one line in one unit (ppm below 1e-4); without U, the stated significant digits."""
    out = io.StringIO()
    con = PlainConsole(out, out=io.StringIO())
    con.result("outer ±10 deg/s",
               Figure("k", 1.00029253, 3.87e-6), Figure("ω0", 0.00206612, 3.76e-5, "°/s",
                                                         signed=True),
               Figure("δ(+)", -1.0049e-7, 1.2e-7, RELATIVE, signed=True),
               Figure("δ(−)", -1.349e-7, 1.17e-7, RELATIVE, signed=True))
    con.result("outer +10 deg/s, 2 turns timed",
               Figure("turn 1", -1.5108e-7, unit=RELATIVE, signed=True, digits=3),
               Figure("turn 2", -7.9249e-8, unit=RELATIVE, signed=True, digits=3))
    con.result("big", Figure("δ", 2.5e-4, 1.07e-5, RELATIVE, signed=True))
    # magnitudes under the certificate's one rule: resolved when |value| > U, else "< |v| + U"
    con.result("σ", Figure("resolved", 5.0e-8, 2.0e-8, RELATIVE, magnitude=True),
               Figure("not", 3.0e-8, 4.0e-8, RELATIVE, magnitude=True),
               Figure("no U", 3.0e-8, None, RELATIVE, magnitude=True))
    assert out.getvalue().splitlines() == [
        "  outer ±10 deg/s: k = 1.0002925 ± 0.0000039, ω0 = +0.002066 ± 0.000038 °/s, "
        "δ(+) = \u22120.10 ± 0.12 ppm, δ(\u2212) = \u22120.13 ± 0.12 ppm",
        "  outer +10 deg/s, 2 turns timed: turn 1 = \u22120.151 ppm, turn 2 = \u22120.0792 ppm",
        "  big: δ = +0.0250 ± 0.0011 %",
        "  σ: resolved = 0.050 ± 0.020 ppm, not = < 0.070 ppm, no U = \u2014"]


def test_prompts_on_the_certificate_say_who_answered() -> None:
    events = [{"event": "prompt", "session": 1, "text": "Mount the FOG", "answered": "yes",
               "answered_by": "--yes", "answered_utc": "2026-11-22T14:13:11.000+00:00"},
              {"event": "prompt", "session": 2, "text": "Connect the sensor",
               "answered": "yes", "answered_by": "operator", "answer": "",
               "answered_utc": "2026-11-22T15:00:00.000+00:00"},
              {"event": "prompt", "session": 2, "text": "Old log", "answered": "operator"}]
    (table,) = prompt_blocks(decode_all(events))
    assert [r[3] for r in table.rows] == [
        "confirmed by --yes (unattended run: nobody was asked)",
        "confirmed by the operator (Enter)", "confirmed by the operator (Enter)"]
    assert table.rows[1][2] == "2026-11-22 15:00:00 UTC"
    assert "unattended" in table.notes[0]
    assert prompt_blocks([]) == ()


def test_software_note_names_every_version_involved() -> None:
    events = [{"event": "session_start", "session": 1, "version": "0.1.0"},
              {"event": "session_start", "session": 2, "version": "0.2.0"}]
    note = software_note("0.1.0", decode_all(events), "0.2.0",
                         "run-1").text
    assert note == ("Software: run with ratebench 0.1.0 (session 1), 0.2.0 (session 2); "
                    "certificate issued by ratebench 0.2.0. Run directory: run-1.")


def test_a_warning_logged_by_a_twin_is_a_json_line_too() -> None:
    """--log-json: every stderr line is one JSON object. A twin's logged warning (the drive
    twin's lost heartbeat, seen in CI on a starved machine) used to reach stderr through
    Python's last-resort handler as plain text, and broke the log collector's parse."""
    import logging

    first, stream = io.StringIO(), io.StringIO()
    root = logging.getLogger()
    before = list(root.handlers)
    try:
        JsonConsole(first, out=io.StringIO())
        JsonConsole(stream, out=io.StringIO())        # the newest console takes the logs
        assert [type(h).__name__ for h in root.handlers].count("_LogLines") == 1
        logging.getLogger("sims.drive_twin").warning(
            "drive twin %s: no heartbeat from node %d for %.3f s: %s", "outer", 2, 0.512,
            "QUICK_STOP")
    finally:
        root.handlers[:] = before
    assert first.getvalue() == ""
    (rec,) = [json.loads(line) for line in stream.getvalue().splitlines()]
    assert rec["event"] == "log" and rec["level"] == "WARNING"
    assert rec["logger"] == "sims.drive_twin"
    assert rec["text"] == "drive twin outer: no heartbeat from node 2 for 0.512 s: QUICK_STOP"
