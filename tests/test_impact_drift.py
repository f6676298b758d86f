"""`bench impact` on the drift kind (issue 58, the second acceptance case): the X gyro's
DMM reads every voltage (1 + g) times the true one, which the lab does not know; a short
drift run under the lab register is issued with it; the DMM's calibration later finds the
gain error g; `bench impact` analyses the run's raw captures again with the correction
(every reading divided by 1 + g, docs/method.md B, "The drift kind's instrument
corrections") and each figure moves by its hand-derived first-order effect: -g w for the
X gyro's own and apparent drift, (app_y / r^2)(-g app_x) rad for the azimuth,
(app_x / W_h)(-g app_x) for W_h, nothing for the Y gyro.

One short run (4 cycles a position, 2 timing cycles) keeps the wall time small.
"""

from __future__ import annotations

import datetime as dt
import json
import math
import re
from pathlib import Path
from typing import Any

import pytest
import yaml

from bench.app.register import Register
from tests import registers as lab
from tests.conftest import CONFIGS

DMM_SERIAL = "MY60000412"
QUALITY = "Q. Manager"
#: the X DMM's true gain error: its effect on the azimuth (about 9.8 g deg here) is about
#: one U of the short run, on X's apparent drift about half a U (both over U/3: marked)
G_REL = 2.0e-3
G_U_REL = 1.0e-4


def _drift_files(folder: Path) -> Path:
    """The drift demo's procedure, short, and its stand with the X DMM's serial stated (the
    inventory's item) and its true gain error g in the twins' truth."""
    folder.mkdir(parents=True)
    stand = yaml.safe_load((CONFIGS / "stands" / "sim-gyro-platform.yaml").read_text())
    stand["platform"]["gyros"]["x"]["dmm"]["serial"] = DMM_SERIAL
    stand["sim"]["dmm"]["gain_error_rel"] = {"x": G_REL}
    (folder / "stand.yaml").write_text(yaml.safe_dump(stand))
    proc = yaml.safe_load((CONFIGS / "procedures" / "drift-demo.yaml").read_text())
    proc.update(stand="stand.yaml", cycles=4, timing_cycles=2, settle_s=1, gap_s=0.2)
    (folder / "drift.yaml").write_text(yaml.safe_dump(proc))
    return folder / "drift.yaml"


def test_impact_of_a_dmm_gain_error_on_a_drift_run(tmp_path: Path) -> None:
    url = lab.sqlite_register(tmp_path / "register")
    labf = lab.lab_file(tmp_path / "lab", url)
    with Register.open(url, migrate=False) as reg:
        quality = reg.authenticate(QUALITY, lab.password(QUALITY), "quality")
        reg.add_equipment(quality, DMM_SERIAL, "Keysight 34465A", "SIM-CAL-34465A-0212",
                          "Cal Lab", dt.date.today() + dt.timedelta(days=300))
    runs = tmp_path / "runs"
    made, rec = lab.registered_run(_drift_files(tmp_path / "files"), runs, labf, url)
    assert rec.result is not None
    uid = rec.uid
    assert any(i.get("serial") == DMM_SERIAL and i.get("where") == "platform.gyros.x.dmm"
               for i in rec.items), rec.items
    number = lab.issue_then_find_out(made, labf, url, DMM_SERIAL, "SIM-CAL-34465A-0299",
                                     G_REL, G_U_REL)

    report = tmp_path / "impact.json"
    folder = tmp_path / "report"
    got = lab.cli_in(lab.password(QUALITY) + "\n", "impact", DMM_SERIAL, "--lab", str(labf),
                     "--runs", str(runs), "--json", str(report), "--report", str(folder),
                     "--as", QUALITY, "--password-stdin")
    assert got.returncode == 0, got.stderr
    print(got.stdout)
    doc = json.loads(report.read_text())
    [run] = doc["runs"]
    assert (run["uid"], run["status"], run["where"], run["number"]) == \
        (uid, "re-analysed", "platform.gyros.x.dmm", number)
    shift = {(f["where"], f["name"]): f for f in run["figures"]}

    issued = json.loads(rec.result)["drift"]
    x, y = issued["axes"]["x"], issued["axes"]["y"]
    app_x, app_y = x["apparent_dph"], y["apparent_dph"]
    r2 = app_x ** 2 + app_y ** 2
    # hand-derived first-order effects of dividing X's readings by 1 + g (docs/method.md B)
    hand = {("drift.axes.x", "own_dph"): -G_REL * x["own_dph"],
            ("drift.axes.x", "apparent_dph"): -G_REL * app_x,
            ("drift", "azimuth_deg"): math.degrees(app_y / r2 * -G_REL * app_x),
            ("drift", "earth_horizontal_dph"): app_x / math.sqrt(r2) * -G_REL * app_x}
    for key, want in hand.items():
        f = shift[key]
        assert abs(f["shift"] - want) <= 0.01 * abs(want), (key, f, want)
        print(f"{key}: shift {f['shift']:.6g}, hand-derived {want:.6g} "
              f"({f['shift'] / want - 1:+.2%}), shift/U {f['shift_over_u']:+.3f}")
    # the Y gyro's DMM was not corrected: its figures do not move at all
    for name in ("own_dph", "apparent_dph"):
        assert shift[("drift.axes.y", name)]["shift"] == 0.0
    assert shift[("drift", "azimuth_deg")]["marked"]
    assert shift[("drift.axes.x", "apparent_dph")]["marked"]
    assert not shift[("drift.axes.y", "own_dph")]["marked"]
    assert run["checks_changed"] == []      # 0.35 deg/h moves by 0.0007: still within 0.5
    assert "conformity: no outcome changes" in got.stdout
    assert not (made / "corrections.json").exists()
    _check_report(folder, doc, report.read_text(), number, url)


def _squeezed(text: str) -> str:
    """Text without whitespace: a table cell the PDF wraps reads as one word again."""
    return "".join(text.split())


def _check_report(folder: Path, doc: dict[str, Any], json_text: str, number: str,
                  url: str) -> None:
    """The PDF's and the HTML's text state the JSON's numbers: the summary row first, then
    the certificate's page with every figure; the customer's draft names the certificate
    and the marked figures; the audit entry holds each file's SHA-256."""
    import hashlib

    import pypdfium2

    stem = f"impact-{DMM_SERIAL.lower()}"
    assert (folder / f"{stem}.json").read_text() == json_text
    [run] = doc["runs"]
    big = max(run["figures"], key=lambda f: abs(f["shift_over_u"]))
    row = (f"{run['uid']} {number} Demo customer {big['where']} {big['name']} "
           f"{big['shift']:+.3g} {big['unit']} {big['shift_over_u']:+.3g} * none")
    pdf = pypdfium2.PdfDocument(folder / f"{stem}.pdf")
    pages = [pdf[i].get_textpage().get_text_range() for i in range(len(pdf))]
    assert len(pages) >= 2, pages
    print("--- the report's first page ---\n" + pages[0])
    assert "Summary" in pages[0] and _squeezed(row) in _squeezed(pages[0]), (row, pages[0])
    page = next(p for p in pages[1:] if f"Certificate {number}" in p)
    html_text = (folder / f"{stem}.html").read_text()
    for f in run["figures"]:
        cells = (f"{f['where']} {f['name']} {f['unit']} {f['issued']:.7g} "
                 f"{f['corrected']:.7g} {f['shift']:+.3g} {f['u_issued']:.3g} "
                 f"{f['shift_over_u']:+.3g}" + (" *" if f["marked"] else ""))
        assert _squeezed(cells) in _squeezed(page), (cells, page)
        assert f"<td class=\"r\">{f['shift']:+.3g}</td>" in html_text, cells
    assert _squeezed(row) in _squeezed(re.sub(r"<[^>]+>", " ", html_text))
    draft = (folder / "notification-demo-customer.txt").read_text()
    assert draft.startswith("DRAFT") and f"Certificate {number}" in draft
    assert "To: Demo customer" in draft and "Attention: J. Smith" in draft
    for f in (f for f in run["figures"] if f["marked"]):
        assert (f"{f['where']} {f['name']}: issued {f['issued']:.7g}, corrected "
                f"{f['corrected']:.7g} {f['unit']}, shift {f['shift']:+.3g} "
                f"({f['shift_over_u']:+.3g} * U)") in draft, draft
    assert "conformity statements: no outcome changes" in draft
    assert (folder / "notification-demo-customer.html").read_text().count(number) == 1
    with Register.open(url, migrate=False) as reg:
        [entry] = [r for r in reg.audit_rows() if r.action == "impact assessed"]
    detail = entry.detail if isinstance(entry.detail, dict) else json.loads(
        str(entry.detail))
    assert detail["certificates"] == [number] and detail["finding"]["error"] == G_REL
    assert detail["report"][f"{stem}.pdf"] == \
        hashlib.sha256((folder / f"{stem}.pdf").read_bytes()).hexdigest()


def test_an_offset_and_an_amplitude_correction_move_no_figure_and_show_as_rows(
        tmp_path: Path) -> None:
    """A DMM offset o cancels between the signed integral's two equal halves and the
    generator's amplitude drops out of w (docs/method.md B): corrected for them, every
    figure is the uncorrected one to rounding, and each correction is a budget row with
    its u = U / 2 and c = 0; a gain correction is a row with c = -w / (1 + g)."""
    from dataclasses import replace

    from procedures.drift_pulse import analysis as dp
    from procedures.drift_pulse.budgets import CorrectionInput
    from procedures.drift_pulse.corrections import read_corrections
    from tests.drift_cycles import paper_truth, record_cycles

    shape = dp.SHAPES["rectangular"]
    recs, _ = record_cycles(paper_truth(angle_noise_arcsec=1.0), shape, cycles=4)
    k_as = {"x": 2.0, "y": 2.0}
    (tmp_path / "corrections.json").write_text(json.dumps({"corrections": [
        {"where": "platform.gyros.x.dmm", "quantity": "offset_error_v", "value": 0.01,
         "U": 0.002},
        {"where": "platform.awg", "quantity": "amplitude_error_rel", "value": 0.01,
         "U": 0.004},
        {"where": "axes.outer.counter", "quantity": "timebase_offset_rel", "value": 1e-7}]}))
    corr = read_corrections(tmp_path)
    read = {g: [replace(r, u_v=r.u_v + (0.01 if g == "x" else 0.0)) for r in rs]
            for g, rs in recs.items()}            # what a DMM off by o = 10 mV reads
    again = {g: [replace(r, u_v=corr.readings(g, r.u_v)) for r in rs] for g, rs in read.items()}
    assert max(abs(a.u_v - r.u_v).max() for a, r in zip(again["x"], recs["x"], strict=True)) \
        < 1e-15 and again["y"][0].u_v is read["y"][0].u_v    # y's DMM: untouched
    stated = {g: dp.StatedErrors(corrections=tuple(
        CorrectionInput(c.where, c.quantity, c.value, c.ustd) for c in corr.of_gyro(g)))
        for g in recs}
    plain = dp.analyze(recs, shape, k_as, 70.0)
    fixed = dp.analyze(again, shape, k_as, 70.0, stated)
    for g in recs:
        for name in ("own_dph", "apparent_dph", "own_u_dph"):
            assert math.isclose(getattr(fixed.axes[g], name), getattr(plain.axes[g], name),
                                rel_tol=1e-9), (g, name)
    rows = {t.quantity.split(" (")[0]: t for t in fixed.axes["x"].own_budget.terms}
    offset = rows["DMM offset correction o applied"]
    amplitude = rows["pulse generator amplitude correction a applied"]
    assert (offset.estimate, offset.ustd, offset.sensitivity) == (0.01, 0.001, 0.0)
    assert (amplitude.estimate, amplitude.ustd, amplitude.sensitivity) == (0.01, 0.002, 0.0)
    assert "pulse generator amplitude correction a applied" in \
        {t.quantity.split(" (")[0] for t in fixed.axes["y"].own_budget.terms}
    assert "DMM offset correction o applied" not in \
        {t.quantity.split(" (")[0] for t in fixed.axes["y"].own_budget.terms}
    gain = dp.analyze(recs, shape, k_as, 70.0, {"x": dp.StatedErrors(corrections=(
        CorrectionInput("platform.gyros.x.dmm", "gain_error_rel", 2e-3, 5e-5),))})
    [row] = [t for t in gain.axes["x"].own_budget.terms if t.quantity.startswith("DMM gain")]
    assert row.sensitivity == -gain.axes["x"].own_dph / (1 + 2e-3) and row.ustd == 5e-5

    (tmp_path / "corrections.json").write_text(json.dumps({"corrections": [
        {"where": "platform.gyros.x.dmm", "quantity": "gain_error_rel", "value": "2e-3"}]}))
    with pytest.raises(ValueError, match=r"corrections\.json: corrections\[0\]\.value: a "
                                         r"finite number, got '2e-3'"):
        read_corrections(tmp_path)


def test_the_as_found_error_is_the_quantity_of_the_items_place() -> None:
    """A counter's as-found error is its time-base offset, a drift DMM's its gain error,
    the pulse generator's its amplitude error; an item without a correction model (a
    drive) gets none, and `bench impact` lists its runs as not re-analysed."""
    from bench.app.impact import Finding, correction_entry

    f = Finding("S-1", "model", "C-2", "Cal Lab", dt.date(2026, 11, 1), "out", 3e-3, 2e-4,
                None, None)
    got = {w: None if c is None else c.quantity for w in ("axes.outer.counter",
                                                            "platform.gyros.y.dmm",
                                                            "platform.awg",
                                                            "axes.outer.drive", "platform.dmm")
           for c in [correction_entry(f, w)]}
    assert got == {"axes.outer.counter": "timebase_offset_rel",
                   "platform.gyros.y.dmm": "gain_error_rel",
                   "platform.awg": "amplitude_error_rel",
                   "axes.outer.drive": None, "platform.dmm": None}
    entry = correction_entry(f, "platform.gyros.y.dmm")
    assert entry is not None and (entry.value, entry.U, entry.serial) == \
        (3e-3, 2e-4, "S-1")
