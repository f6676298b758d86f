"""Issue 43: the item as received and as left, the decision rule's agreement, the settings
that differ from their read-back and the accreditation statement (ISO/IEC 17025 7.1.3,
7.8.2.1 g, 7.8.4.1 b): stated from the procedure file, meta.json and the lab's settings,
'not stated' where nobody stated them, the same in the certificate and the DCC.

Truth is the files written here by hand; the DCC test reads the session's demo run (a copy).
"""

from __future__ import annotations

import json
from pathlib import Path

from lxml import etree

from bench.app.certificate.item import (
    NOT_STATED,
    TWIN_WATCHDOG_WHY,
    item_record,
    readback_differences,
    setting_statements,
    statements,
)
from bench.app.dcc.writer import DccInputs, build_dcc
from bench.core.lab import Lab
from bench.report.certificate.parts import Sources
from tests.conftest import DemoRun

NS = {"dcc": "https://ptb.de/dcc"}
DRIVE = ("Bench CiA 402 rate-table drive, serial 41001; read back: drive.factor 0x608F = "
         "1048576/1, drive.heartbeat consumer 0x1016:1 = node 127, 5000 ms, drive.quick stop "
         "option code 0x605A = 2")


def test_nothing_stated_is_printed_not_stated() -> None:
    rows = dict(item_record(Sources({"decision_rule": "simple"})).rows)
    for label in ("Date of receipt", "Condition on receipt", "State of the results",
                  "Adjustments made", "As-found results", "As-left results"):
        assert rows[label] == NOT_STATED, label
    assert rows["Decision rule"] == ("simple acceptance (ILAC-G8:09/2019 4.2.1); the "
                                     "customer's agreement: not stated")


def test_as_left_run_links_its_as_found_run(tmp_path: Path) -> None:
    found = tmp_path / "20261120-090000-found"
    found.mkdir()
    (found / "result.json").write_text(json.dumps({"verdict": "fail", "checks": [
        {"axis": "outer", "set_rate_dps": 10.0, "quantity": "rate_error",
         "value_rel": 1.5e-6, "u_rel": 5e-8, "tolerance_rel": 1e-6, "verdict": "fail"}]}))
    left = tmp_path / "20261121-100000-left"
    left.mkdir()
    src = Sources({"decision_rule": "guard-band"}, left,
                  meta={"calibration_state": "as-left", "adjustment_note": "gain retuned"},
                  procedure_file={
                      "item": {"received": "2026-11-20", "condition": "crated, undamaged",
                               "as_found_run": found.name,
                               "adjustments": ["rate loop gain retuned (MP-7)"]},
                      "decision_rule_agreement": {"agreed_with": "J. Smith", "agreed_on":
                                                  "2026-11-18", "reference": "PO 4711"}})
    record = item_record(src)
    rows = dict(record.rows)
    assert rows["Date of receipt"] == "2026-11-20"
    assert rows["Condition on receipt"] == "crated, undamaged"
    assert rows["State of the results"] == "as left (after adjustment)"
    assert rows["Adjustments made"] == "rate loop gain retuned (MP-7); gain retuned"
    assert rows["As-found results"] == f"run {found.name}: FAIL, its checks below"
    assert rows["As-left results"].startswith(f"this certificate's results (run {left.name}")
    assert rows["Decision rule"] == ("guarded acceptance, w = U (ILAC-G8:09/2019 4.2.2); "
                                     "agreed with J. Smith on 2026-11-18 (PO 4711)")
    assert record.as_found is not None and record.as_found.verdict == "fail"
    lines = statements(record)
    assert (f"As found (run {found.name}): axis outer, rate_error at 10.0 deg/s: value 1.5e-06 "
            "rel, verdict fail.") in lines
    # a run id that is not beside this run is named, its results not invented
    src.procedure_file["item"]["as_found_run"] = "20261101-000000-gone"
    assert dict(item_record(src).rows)["As-found results"] == (
        "run 20261101-000000-gone (not found beside this run: its results are not restated "
        "here)")


def test_a_setting_unlike_its_read_back_is_noted_and_on_twins_why_once() -> None:
    stand = {"stand": {"simulated": True}, "axes": {
        a: {"drive": {"watchdog_ms": 1500, "counts_per_rev": 1048576}} for a in ("outer", "inner")}}
    src = Sources({"instruments": {"outer": {"drive": DRIVE}, "inner": {"drive": DRIVE}},
                   "stand": {"simulated": True}}, stand_file=stand)
    lines = readback_differences(src)
    assert lines == (
        "axis outer drive: watchdog ms 1500 in the stand file; the drive read back 0x1016:1 = "
        "5000 ms",
        "axis inner drive: watchdog ms 1500 in the stand file; the drive read back 0x1016:1 = "
        "5000 ms",
        TWIN_WATCHDOG_WHY)
    # a real stand: the difference is stated, no twin's reason
    stand["stand"] = {"simulated": False}
    real = Sources({"instruments": {"outer": {"drive": DRIVE}}}, stand_file=stand)
    assert readback_differences(real) == (lines[0],)
    # as the drive keeps it: nothing to note
    stand["axes"]["outer"]["drive"]["watchdog_ms"] = 5000
    assert readback_differences(real) == ()


def _statements(root: etree._Element, ref_type: str) -> list[str]:
    return [s.findtext("dcc:declaration/dcc:content", "", NS)
            for s in root.iterfind(".//dcc:statement", NS)
            if ref_type in (s.get("refType") or "").split()]


def test_the_dcc_states_them_and_accreditation_only_when_the_lab_does(
        demo_run: DemoRun, tmp_path: Path) -> None:
    run = demo_run.copy_to(tmp_path / "runs")
    result = json.loads((run / "result.json").read_text())
    plain = build_dcc(DccInputs(Sources.load(result, run), lab=Lab(name="Lab"))).getroot()
    assert _statements(plain, "ratebench_accreditation") == []
    items = _statements(plain, "ratebench_itemState")
    assert "Date of receipt: not stated." in items
    assert any(s.startswith("Decision rule: guarded acceptance") for s in items)
    readback = _statements(plain, "ratebench_settingReadBack")
    src = Sources.load(result, run)
    assert readback == list(setting_statements(item_record(src)))
    assert readback[-1] == TWIN_WATCHDOG_WHY and "0x1016:1 = 5000 ms" in readback[0]
    stated = build_dcc(DccInputs(src, lab=Lab(name="Lab", accreditation="DAkkS D-K-12345-01"))
                       ).getroot()
    assert _statements(stated, "ratebench_accreditation") == [
        "Accreditation: DAkkS D-K-12345-01"]
