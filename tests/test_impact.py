"""`bench impact` (issue 58) end to end on the twins: a counter whose time base is off by
e, which the lab does not know, times a short check run under the lab register; its
calibration later finds it out with the as-found error e; `bench impact` finds the run,
analyses its raw captures again with the correction, and each rate error moves by about
+e (the offset had moved it by -e, docs/method.md A1), back onto the twin's truth.
A run the register holds whose raw data is nowhere in the runs folders is listed as
"raw data not found", not re-analysed.
"""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path
from typing import Any

import pytest
import yaml

from bench.app.impact import finding_of, touched
from bench.app.register import Register
from bench.app.register.store import (
    AuthError,
    Calibration,
    Equipment,
    RegisterError,
    RunRecord,
)
from bench.core import rundir_layout as layout
from sims.truth import AxisTruth
from tests.conftest import check_procedure, cli, run_dir_of
from tests.registers import (
    cli_in,
    issue_then_find_out,
    lab_file,
    password,
    registered_run,
    sqlite_register,
)

SERIAL = "MY62000999"
QUALITY = "Q. Manager"
#: the counter's true time-base offset: about 3 x the rate error's U of this check run
#: (U ~ 1.0e-7 at 50 deg/s from 2 turns a direction)
E_REL = 3.0e-7
E_U_REL = 1.0e-9
TOLERANCE_REL = 2.4e-7


def _stand_with_offset(proc: Path, seed: int, e_rel: float) -> dict[str, Any]:
    """The check run's stand with the outer counter's serial stated (the inventory's item)
    and its true time-base offset e in the twins' truth."""
    stand_file = proc.parent / f"stand-{seed}.yaml"
    stand = yaml.safe_load(stand_file.read_text())
    stand["axes"]["outer"]["counter"]["serial"] = SERIAL
    outer = stand["sim"]["axes"]["outer"]
    outer["serials"]["counter"] = SERIAL
    outer["counter"] = {"timebase_offset_rel": e_rel}
    stand_file.write_text(yaml.safe_dump(stand))
    return dict(stand)


def test_impact_finds_the_run_and_the_correction_moves_the_rate_error_by_e(
        tmp_path: Path) -> None:
    url = sqlite_register(tmp_path / "register")
    labf = lab_file(tmp_path / "lab", url)
    with Register.open(url, migrate=False) as reg:
        quality = reg.authenticate(QUALITY, password(QUALITY), "quality")
        reg.add_equipment(quality, SERIAL, "Keysight 53230A", "C-2025-999", "Cal Lab",
                          dt.date.today() + dt.timedelta(days=300))
    proc = check_procedure(tmp_path / "files", seed=3)
    # a rate-error tolerance the offset run fails (|delta| - U above it) and its corrected
    # figures pass (|delta| + U within it): the conformity outcome the finding changes
    procedure = yaml.safe_load(proc.read_text())
    procedure["tolerance"] = {"rate_error": [{"rel": TOLERANCE_REL}]}
    proc.write_text(yaml.safe_dump(procedure))
    stand = _stand_with_offset(proc, 3, E_REL)
    runs = tmp_path / "runs"
    made, rec = registered_run(proc, runs, labf, url)
    assert rec.result is not None
    uid = rec.uid
    assert any(i.get("serial") == SERIAL for i in rec.items)
    with Register.open(url, migrate=False) as reg:
        # a second run of the same counter the register holds, whose raw data is in no
        # runs folder: listed, never guessed
        reg.register_run("run-without-raw-data", "test bench", None, rec.version, True,
                         rec.inputs, rec.items)
        reg.deliver_result("run-without-raw-data", "session", rec.result.encode(), rec.raw)
    number = issue_then_find_out(made, labf, url, SERIAL, "C-2026-999", E_REL, E_U_REL)

    report = tmp_path / "impact.json"
    got = cli_in(password(QUALITY) + "\n", "impact", SERIAL, "--lab", str(labf),
                 "--runs", str(runs), "--json", str(report), "--report",
                 str(tmp_path / "report"), "--as", QUALITY, "--password-stdin")
    assert got.returncode == 0, got.stderr
    lines = got.stdout.splitlines()
    assert lines[0].startswith(f"Impact of Keysight 53230A serial {SERIAL}: as-found error "
                               f"{E_REL:g}"), lines[0]
    assert "runs that used it since the inventory's first record: 2; re-analysed with the " \
           "correction: 1; raw data not found: 1" in lines[1], got.stdout
    doc = json.loads(report.read_text())
    by_uid = {r["uid"]: r for r in doc["runs"]}
    assert set(by_uid) == {uid, "run-without-raw-data"}
    assert by_uid["run-without-raw-data"]["status"] == "raw data not found"
    assert by_uid["run-without-raw-data"]["figures"] == []
    done = by_uid[uid]
    assert done["status"] == "re-analysed" and done["where"] == "axes.outer.counter"
    assert done["number"] == number and done["revisions"] == [number]
    assert by_uid["run-without-raw-data"]["number"] is None

    # the twin's truth: the per-turn rate's deviation from w_set (harmonic mean over angle)
    truth_rel = AxisTruth.from_mapping(stand["sim"]["axes"]["outer"]).mean_turn_rate_rel()
    issued = json.loads(rec.result)
    for entry in issued["axes"]["outer"]["rates"]:
        where = f"axes.outer.rates[{entry['set_rate_dps']:+g} deg/s]"
        fig = next(f for f in done["figures"]
                   if f["where"] == where and f["name"] == "rate_error_rel")
        delta, big_u = entry["rate_error_rel"], entry["rate_error_U_rel"]
        assert fig["issued"] == delta and fig["u_issued"] == big_u
        # hand-derived: every rate x (1 + e), so delta' = (1 + delta)(1 + e) - 1
        hand = E_REL * (1.0 + delta)
        assert abs(fig["shift"] - hand) <= 0.01 * abs(hand), (fig, hand)
        assert fig["marked"] and 2.0 < fig["shift_over_u"] < 4.0, fig
        # the issued figure was off the truth by about -e, within its U; the corrected
        # one's interval covers the truth
        assert abs(delta - (truth_rel - E_REL)) <= big_u, (delta, truth_rel, big_u)
        assert abs(fig["corrected"] - truth_rel) <= big_u, (fig, truth_rel)
        print(f"{where}: e {E_REL:.3g}, issued {delta:.4g} +/- {big_u:.3g}, corrected "
              f"{fig['corrected']:.4g}, shift {fig['shift']:.4g} ({fig['shift_over_u']:.3f} "
              f"U), truth {truth_rel:.4g}")
    changed = {(c["set_rate_dps"], c["quantity"], c["issued"], c["corrected"])
               for c in done["checks_changed"]}
    assert changed == {(50.0, "rate_error", "fail", "pass"),
                       (-50.0, "rate_error", "fail", "pass")}, done["checks_changed"]
    assert "conformity CHANGES: outer 50 deg/s rate_error: issued fail, corrected pass" \
        in got.stdout
    # the same seed without the offset (no register: a reference, never issued): each
    # corrected figure equals it within 1 % of its U, the intra-turn figures too: the
    # corrected edges choose the FOG samples as a true time base would have (the offset
    # counter's had put the -50 deg/s window a sample late: 1.5 % of U before the
    # correction re-chose it, docs/method.md A1)
    ref_proc = check_procedure(tmp_path / "reference", seed=3)
    _stand_with_offset(ref_proc, 3, 0.0)
    ref = cli("run", str(ref_proc), "--yes", "--quiet", "--out", str(tmp_path / "ref-runs"))
    assert ref.returncode in (0, 1), ref.stderr[-3000:]
    plain = json.loads((run_dir_of(ref) / layout.RESULT).read_text())
    for entry in plain["axes"]["outer"]["rates"]:
        where = f"axes.outer.rates[{entry['set_rate_dps']:+g} deg/s]"
        for fig in (f for f in done["figures"] if f["where"] == where):
            same = entry[fig["name"]]
            assert abs(fig["corrected"] - same) <= 0.01 * fig["u_issued"], (fig, same)
    print(got.stdout)
    assert f"{uid}" in got.stdout and " *" in got.stdout
    # the copy was corrected, never the run folder
    assert not (made / "corrections.json").exists()
    assert (made / layout.RESULT).read_bytes() == rec.result_bytes
    with Register.open(url, migrate=False) as reg:
        entries = [r for r in reg.audit_rows() if r.action == "impact assessed"]
        assert len(entries) == 1 and entries[0].object == SERIAL
        assert entries[0].actor == QUALITY
        assert uid in str(entries[0].detail) and number in str(entries[0].detail)
    # the report (--report): its summary states the conformity outcomes that change and
    # the run whose raw data is not found; the draft to the run's customer (none stated
    # here) names the certificate and the changed statements, and no unissued run
    import pypdfium2

    pdf = pypdfium2.PdfDocument(tmp_path / "report" / f"impact-{SERIAL.lower()}.pdf")
    first = "".join(pdf[0].get_textpage().get_text_range().split())
    for rate in ("50", "-50"):
        assert f"outer{rate}deg/srate_error:fail->pass" in first, first
    assert "run-without-raw-data" in first and "rawdatanotfound" in first
    draft = (tmp_path / "report" / "notification-customer-not-stated.txt").read_text()
    assert f"Certificate {number} (run {uid})" in draft and "run-without-raw-data" not in draft
    assert "conformity statement changes: outer 50 deg/s rate_error: fail -> pass" in draft


def _record(uid: str, day: str) -> RunRecord:
    return RunRecord(uid, "bench", None, "v", True, {}, (), f"{day}T10:00:00Z", "bench")


def test_the_runs_touched_are_those_since_the_last_calibration_found_in_tolerance(
        tmp_path: Path) -> None:
    """A finding touches the runs from the last calibration that found the item in
    tolerance up to the calibration that found it out; runs of another item are not the
    item's (the register's `runs_using`)."""
    day = dt.date.fromisoformat
    item = Equipment(SERIAL, "Keysight 53230A", "C-3", "Cal Lab", day("2027-01-01"),
                     calibrations=(
                         Calibration("C-1", "Cal Lab", None, day("2025-01-01")),
                         Calibration("C-2", "Cal Lab", day("2025-01-01"), day("2026-01-01"),
                                     found="in", found_error=1e-9),
                         Calibration("C-3", "Cal Lab", day("2026-01-10"), day("2027-01-01"),
                                     found="out", found_error=E_REL, found_error_u=E_U_REL)))
    f = finding_of(item)
    assert (f.certificate, f.error, f.error_u) == ("C-3", E_REL, E_U_REL)
    assert (f.since, f.since_certificate) == (day("2025-01-01"), "C-2")
    runs = [_record("before", "2024-12-31"), _record("first", "2025-01-01"),
            _record("later", "2025-06-30"), _record("last", "2026-01-10"),
            _record("after", "2026-01-11")]
    assert [r.uid for r in touched(runs, f)] == ["first", "later", "last"]
    with pytest.raises(RegisterError, match="no as-found error"):
        finding_of(Equipment(SERIAL, "m", "C-1", "Cal Lab", day("2027-01-01"),
                             calibrations=item.calibrations[:1]))

    url = sqlite_register(tmp_path / "register")
    item_of = {"where": "axes.outer.counter", "item": "counter", "serial": SERIAL}
    other = {"where": "axes.inner.counter", "item": "counter", "serial": "MY-OTHER"}
    with Register.open(url, migrate=False) as reg:
        reg.register_run("uses-it", "b", None, "v", True, {}, [item_of, other])
        reg.register_run("another-counter", "b", None, "v", True, {}, [other])
        assert [r.uid for r in reg.runs_using(SERIAL)] == ["uses-it"]
        assert {r.uid for r in reg.runs_using("MY-OTHER")} == {"uses-it", "another-counter"}
        operator = reg.authenticate("A. Ivanova", password("A. Ivanova"), "operator")
        with pytest.raises(AuthError, match="quality"):
            reg.impact_assessed(operator, SERIAL, {})


def test_the_service_records_an_impact_assessment_for_a_logged_in_quality_account(
        tmp_path: Path) -> None:
    """The register service's ops (over an SQLite register here; PostgreSQL behind it in
    the lab): the runs that used an item, and the audit entry, which needs a logged-in
    quality account."""
    from bench.app.register.service import create_app

    url = sqlite_register(tmp_path / "register")
    item_of = {"where": "axes.outer.counter", "item": "counter", "serial": SERIAL}
    with Register.open(url, migrate=False) as reg:
        quality = reg.authenticate(QUALITY, password(QUALITY), "quality")
        reg.add_equipment(quality, SERIAL, "Keysight 53230A", "C-1", "Cal Lab",
                          dt.date.today() + dt.timedelta(days=30))
        reg.register_run("uses-it", "b", None, "v", True, {}, [item_of])
        client = create_app(reg).test_client()

        def call(op: str, **body: object) -> tuple[int, Any]:
            got = client.post(f"/v1/{op}", json=body)
            return got.status_code, got.get_json()

        code, runs = call("runs_using", serial=SERIAL)
        assert code == 200 and [r["uid"] for r in runs["ok"]] == ["uses-it"]
        assert call("impact_assessed", serial=SERIAL, detail={})[0] == 403   # no login
        code, login = call("authenticate", name="A. Ivanova",
                           password=password("A. Ivanova"), role=None)
        assert code == 200
        token = login["ok"]["token"]
        assert call("impact_assessed", token=token, serial=SERIAL, detail={})[0] == 403
        code, login = call("authenticate", name=QUALITY, password=password(QUALITY),
                           role="quality")
        code, digest = call("impact_assessed", token=login["ok"]["token"],
                            serial=SERIAL, detail={"runs": ["uses-it"]})
        assert code == 200 and isinstance(digest["ok"], str)
        entry = [r for r in reg.audit_rows() if r.action == "impact assessed"]
        assert len(entry) == 1 and entry[0].actor == QUALITY


def test_a_result_is_read_for_the_assessment_and_each_shift_is_over_its_u() -> None:
    """What `bench impact` reads of a result.json (bench/app/impact_codec.py): each entry's
    figures that state a U beside them, by where they are, in their unit; the shift of
    each, corrected minus issued, over the issued U, marked over U/3; the conformity
    outcomes that change; a malformed result is refused naming its key path."""
    from bench.app.impact import check_changes, shifts
    from bench.app.impact_codec import MalformedDocument, result_view

    def result(error_rel: float, k: float, verdict: str) -> str:
        return json.dumps({
            "certificate": {"customer": "ACME", "customer_address": "", "x": 1},
            "checks": [{"axis": "outer", "set_rate_dps": 50, "quantity": "rate_error",
                        "verdict": verdict, "reason": "r"}],
            "axes": {"outer": {
                "rates": [{"set_rate_dps": 50, "rate_error_rel": error_rel,
                           "rate_error_u_rel": 2e-7, "rate_error_U_rel": 2e-7,
                           "turns": 2, "systematic": {"x_U_rel": 1.0}}],
                "pairs": [{"rate_dps": 50.0, "k": k, "k_U": 1e-5, "w0_dps": 0.1,
                           "w0_U_dps": 0.0, "drift_dps_per_h": None,
                           "drift_U_dps_per_h": 1.0}]}},
            "drift": {"azimuth_deg": 30.0, "azimuth_U_deg": 0.5,
                      "axes": {"x": {"own_dph": 0.1, "own_U_dph": 0.02}}}})

    issued = result_view(result(1.0e-6, 1.00010, "fail"))
    again = result_view(result(1.3e-6, 1.00011, "pass"))
    assert issued.customer is not None and issued.customer.customer == "ACME"
    assert issued.customer.customer_address is None          # empty: not stated
    # U 0 (w0) and a null value (drift) state no figure; nested keys are not the entry's
    assert {w: {n: (f.value, f.U, f.unit) for n, f in fs.items()}
            for w, fs in issued.figures.items()} == {
        "axes.outer.rates[+50 deg/s]": {"rate_error_rel": (1.0e-6, 2e-7, "1")},
        "axes.outer.pairs[50 deg/s]": {"k": (1.00010, 1e-5, "1")},
        "drift.axes.x": {"own_dph": (0.1, 0.02, "deg/h")},
        "drift": {"azimuth_deg": (30.0, 0.5, "deg")}}
    moved = {(s.where, s.name): s for s in shifts(issued, again)}
    rate = moved[("axes.outer.rates[+50 deg/s]", "rate_error_rel")]
    assert rate.shift == pytest.approx(3e-7) and rate.shift_over_u == pytest.approx(1.5)
    assert rate.marked
    k = moved[("axes.outer.pairs[50 deg/s]", "k")]
    assert k.shift_over_u == pytest.approx(1.0) and k.marked
    assert moved[("drift", "azimuth_deg")].shift == 0.0
    assert not moved[("drift", "azimuth_deg")].marked
    [change] = check_changes(issued, again)
    assert (change.axis, change.set_rate_dps, change.quantity, change.issued,
            change.corrected) == ("outer", 50.0, "rate_error", "fail", "pass")
    with pytest.raises(MalformedDocument, match=r"result\.json axes\.outer\.rates\[0\]"
                                                r"\.set_rate_dps: expected a number"):
        result_view(json.dumps({"axes": {"outer": {"rates": [{"set_rate_dps": None}]}}}))
    with pytest.raises(MalformedDocument, match=r"result\.json checks\[0\]\.verdict: "
                                                r"missing"):
        result_view(json.dumps({"checks": [{"axis": "x", "quantity": "q"}]}))


def test_the_report_is_its_models_encoding_and_a_malformed_one_is_named() -> None:
    """`bench impact --json`'s document encodes the typed report in its keys' order (the
    largest shift over U derived from the figures, dates as ISO text) and decodes back to
    it; a malformed document is refused naming the key path."""
    from bench.app.impact_codec import (
        FigureShift,
        Finding,
        ImpactReport,
        MalformedDocument,
        RunImpact,
        decode_report,
        encode_report,
    )

    figures = (FigureShift("axes.outer.rates[+50 deg/s]", "rate_error_rel", "1", 1e-6, 1.3e-6,
                           3e-7, 2e-7, 1.5, True),
               FigureShift("axes.outer.rates[-50 deg/s]", "rate_error_rel", "1", 1e-6, 0.7e-6,
                           -3e-7, 1e-7, -3.0, True))
    report = ImpactReport("sqlite:///r", Finding(SERIAL, "m", "C-2", "Cal Lab",
                                                 dt.date(2026, 11, 1), "out", E_REL, None,
                                                 None, None),
                          1.0 / 3.0, (RunImpact(uid="u", registered_utc="t", where="w",
                                                number="RT-1", status="re-analysed",
                                                figures=figures),))
    text = encode_report(report)
    doc = json.loads(text)
    assert list(doc) == ["register", "finding", "mark_fraction_of_U", "runs"]
    assert doc["finding"]["calibrated_on"] == "2026-11-01"
    assert doc["runs"][0]["largest_shift_over_U"] == -3.0
    assert list(doc["runs"][0])[-2:] == ["customer", "largest_shift_over_U"]
    assert text == json.dumps(doc, indent=2) + "\n"
    assert decode_report(text) == report
    doc["runs"][0]["figures"][1]["shift"] = "-3e-7"
    with pytest.raises(MalformedDocument, match=r"impact\.json runs\[0\]\.figures\[1\]\.shift: "
                                                r"expected a number, got text"):
        decode_report(json.dumps(doc))
