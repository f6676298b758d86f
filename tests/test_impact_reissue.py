"""Issue 58's acceptance case on the twins, end to end: a counter whose time base is off by
e (3 x the largest rate error U of the demo, configs/procedures/demo.yaml: the session's
shared demo run), which the lab does not know, times three ladder runs that are issued, and a fourth run left a draft; a fifth run,
timed by another counter (another serial) and without the offset, is issued too and is the
same-seed reference. The counter's calibration then finds it out with the as-found error e
and its U; `bench impact` lists exactly the three issued runs (not the other counter's,
not the draft), each printed shift the hand-derived first-order effect of the correction;
`bench authorise RUN --reason` re-issues each one from a new registered analysis with the
correction applied, whose figures equal the reference's within 1 % of their U, whose
budget carries the correction's own u, and whose certificate (PDF, HTML, DCC) says which
correction was applied and why; the replaced revision reads "withdrawn" in `bench verify`.

A run whose raw data is not found is listed as "raw data not found" and not re-analysed:
tests/test_impact.py tests that (not repeated here).

The check procedure (one rate, two turns a direction) is the shortest that gives every
ladder figure; all five runs share one seed and are made once for the module.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgspec
import pytest
import yaml
from lxml import etree

from bench.analysis.coverage import coverage_factor
from bench.app.certificate import register as issues_of
from bench.app.impact import DRAFT_STATUS
from bench.app.impact_codec import result_view
from bench.app.register import Register
from bench.app.register.runs import run_uid_of
from bench.core import rundir_layout as layout
from tests.conftest import DemoRun, check_procedure, cli
from tests.registers import (
    authorise,
    cli_in,
    issue_then_find_out,
    lab_file,
    password,
    registered_run,
    sqlite_register,
)
from tests.test_authorise import NS, _pages

SERIAL = "MY62000777"          # the counter with the offset
OTHER = "MY62000778"           # another counter, no offset
MODEL = "Keysight 53230A"
QUALITY = "Q. Manager"
SIGNATORY = "P. Petrov"
SEED = 3
REASON = "counter MY62000777 found out of tolerance (time base), certificate corrected"
#: the as-found error's expanded U, a tenth of e: large enough that U visibly grows
U_OVER_E = 0.1

#: the module's runs are made in its first test's set-up: five check runs, five issues,
#: the impact's three analyses and the three corrected re-issues (about 3 min on a busy
#: 2-core machine)
pytestmark = pytest.mark.timeout(900)


@dataclass(frozen=True)
class Case:
    url: str
    e_rel: float
    e_U_rel: float
    reference: dict[str, Any]          # the same-seed run without the offset (issued)
    reference_uid: str
    runs: tuple[Path, ...]             # the three issued runs timed by the offset counter
    issued: tuple[dict[str, Any], ...]   # their results as first issued
    draft_uid: str
    impact: dict[str, Any]             # bench impact --json
    impact_stdout: str
    reissue_stdout: tuple[str, ...]


def _files(folder: Path, serial: str, e_rel: float) -> Path:
    """The check procedure with the outer counter's serial stated (the inventory's item)
    and its true time-base offset in the twins' truth."""
    proc = check_procedure(folder, seed=SEED)
    stand_file = folder / f"stand-{SEED}.yaml"
    stand = yaml.safe_load(stand_file.read_text())
    stand["axes"]["outer"]["counter"]["serial"] = serial
    outer = stand["sim"]["axes"]["outer"]
    outer["serials"]["counter"] = serial
    outer["counter"] = {"timebase_offset_rel": e_rel}
    stand_file.write_text(yaml.safe_dump(stand))
    return proc


def _issue(run: Path, lab: Path, *args: str) -> str:
    done = authorise(run, SIGNATORY, lab, *args, enrolled=False)
    assert done.returncode == 0, done.stdout + done.stderr
    return done.stdout


@pytest.fixture(scope="module")
def case(tmp_path_factory: pytest.TempPathFactory, demo_run: DemoRun) -> Case:
    root = tmp_path_factory.mktemp("impact-reissue")
    url = sqlite_register(root / "register")
    lab = lab_file(root / "lab", url)
    today = dt.date.today()
    with Register.open(url, migrate=False) as reg:
        quality = reg.authenticate(QUALITY, password(QUALITY), "quality")
        for serial in (SERIAL, OTHER):
            reg.add_equipment(quality, serial, MODEL, f"C-2025-{serial}", "Cal Lab",
                              today + dt.timedelta(days=300))
    runs = root / "runs"
    # the fourth run: another counter, no offset; the same seed: the reference
    ref_run, _ = registered_run(_files(root / "files-other", OTHER, 0.0), runs, lab, url)
    reference = json.loads((ref_run / layout.RESULT).read_text())
    assert demo_run.status == 0, demo_run.stderr
    e_rel = 3.0 * max(r["rate_error_U_rel"] for axis in demo_run.result["axes"].values()
                      for r in axis["rates"])
    e_u_rel = U_OVER_E * e_rel
    proc = _files(root / "files-offset", SERIAL, e_rel)
    made = tuple(registered_run(proc, runs, lab, url)[0] for _ in range(3))
    draft, _ = registered_run(proc, runs, lab, url)         # never issued
    for run in (ref_run, *made[:2]):
        _issue(run, lab)
    issue_then_find_out(made[2], lab, url, SERIAL, "C-2026-777", e_rel, e_u_rel)
    issued = tuple(json.loads((r / layout.RESULT).read_text()) for r in made)
    report = root / "impact.json"
    got = cli_in(password(QUALITY) + "\n", "impact", SERIAL, "--lab", str(lab), "--runs",
                 str(runs), "--json", str(report), "--as", QUALITY, "--password-stdin")
    assert got.returncode == 0, got.stderr
    print(got.stdout)
    again = tuple(_issue(run, lab, "--reason", REASON) for run in made)
    return Case(url, e_rel, e_u_rel, reference, run_uid_of(ref_run), made, issued,
                run_uid_of(draft), json.loads(report.read_text()), got.stdout, again)


def _rates(result: dict[str, Any]) -> dict[float, dict[str, Any]]:
    return {r["set_rate_dps"]: r for r in result["axes"]["outer"]["rates"]}


def _entries(result: dict[str, Any]) -> dict[str, dict[str, tuple[float, float]]]:
    """Each rate and pair entry of the outer axis by where it is: its figures that state a
    U, (value, U), as `bench impact` reads them."""
    return {where: {name: (f.value, f.U) for name, f in figures.items()}
            for where, figures in result_view(json.dumps(result)).figures.items()
            if where.startswith("axes.outer.")}


def test_the_impact_lists_exactly_the_three_issued_runs(case: Case) -> None:
    """Not the other counter's run, and the draft only as a draft: never assessed."""
    by_uid = {r["uid"]: r for r in case.impact["runs"]}
    three = {run_uid_of(r) for r in case.runs}
    assessed = {u for u, r in by_uid.items() if r["status"] == "re-analysed"}
    assert assessed == three
    assert all(by_uid[u]["number"] for u in three)
    assert case.reference_uid not in by_uid
    assert set(by_uid) == three | {case.draft_uid}
    assert by_uid[case.draft_uid]["status"] == DRAFT_STATUS
    assert by_uid[case.draft_uid]["figures"] == [] and by_uid[case.draft_uid]["number"] is None
    assert "re-analysed with the correction: 3; raw data not found: 0; drafts never " \
           "issued: 1" in case.impact_stdout.splitlines()[1]
    assert case.impact["finding"]["error"] == case.e_rel
    assert case.impact["finding"]["error_u"] == case.e_U_rel


def _printed(stdout: str, uid: str) -> dict[tuple[str, str], float]:
    """The shifts `bench impact` printed for one run: (where, figure): shift."""
    block = stdout.split(f"\nrun {uid}", 1)[1].split("\nrun ", 1)[0]
    out = {}
    for line in block.splitlines():
        parts = line.split()
        # where (two words: "axes.outer.rates[+50 deg/s]"), figure, unit, issued,
        # corrected, shift, U, shift/U
        if len(parts) >= 9 and parts[0].startswith("axes."):
            out[(" ".join(parts[:2]), parts[2])] = float(parts[6])
    return out


def test_each_printed_shift_is_the_first_order_effect_of_the_correction(case: Case) -> None:
    """docs/method.md A1: the offset moved delta by (1 + delta)/(1 + e) - 1 - delta, about
    -e, and the correction moves it back by e (1 + delta_issued), about +e; k of eq. 5
    moves by -e k / (1 + e) (its counter means x (1 + e)). Each within 1 %."""
    e = case.e_rel
    seen = []
    for run, issued in zip(case.runs, case.issued, strict=True):
        shifts = _printed(case.impact_stdout, run_uid_of(run))
        ref = _rates(case.reference)
        for rate, entry in _rates(issued).items():
            delta = entry["rate_error_rel"]
            # the offset's own effect: the issued delta against the same seed without it
            offset_effect = delta - ref[rate]["rate_error_rel"]
            hand_offset = (1.0 + ref[rate]["rate_error_rel"]) / (1.0 + e) - 1.0 \
                - ref[rate]["rate_error_rel"]
            assert abs(offset_effect - hand_offset) <= 0.01 * e, (rate, offset_effect, -e)
            printed = shifts[(f"axes.outer.rates[{rate:+g} deg/s]", "rate_error_rel")]
            hand = e * (1.0 + delta)
            assert abs(printed - hand) <= 0.01 * abs(hand), (rate, printed, hand)
            seen.append((rate, offset_effect, printed, hand))
        for pair in issued["axes"]["outer"]["pairs"]:
            printed = shifts[(f"axes.outer.pairs[{pair['rate_dps']:g} deg/s]", "k")]
            hand = -e * pair["k"] / (1.0 + e)
            assert abs(printed - hand) <= 0.01 * abs(hand), (printed, hand)
            seen.append(("k", None, printed, hand))
    for s in seen:
        print(f"{s[0]}: offset effect {s[1]}, printed shift {s[2]:.4g}, hand {s[3]:.4g}, "
              f"e {e:.4g}")


def _reissued(run: Path) -> tuple[issues_of.Issue, issues_of.Issue]:
    first, second = issues_of.issues(run)
    return first, second


def test_the_corrected_reissue_equals_the_same_seed_run_without_the_offset(
        case: Case) -> None:
    """Every figure of each re-issue that states a U equals the reference's within 1 % of
    its U; the re-issue is made from the register's new analysis of the run."""
    worst, off = 0.0, []
    for run, out in zip(case.runs, case.reissue_stdout, strict=True):
        first, second = _reissued(run)
        assert (second.revision, second.replaces, second.reason) == \
            (2, first.number, REASON)
        assert "analysed again with the as-found error of " + SERIAL in out
        result = json.loads((run / layout.ISSUED / second.number / layout.RESULT)
                            .read_text())
        uid = run_uid_of(run)
        with Register.open(case.url, migrate=False) as reg:
            rec = reg.run_record(uid)
            assert rec is not None and rec.result is not None
            assert json.loads(rec.result) == result      # issued from the registered result
            kinds = [(ev.kind, ev.detail.reason) for ev in rec.events]
            assert ("analysis", f"corrected re-issue, as-found error of {SERIAL}: {REASON}") \
                in kinds, kinds
            trail = [r for r in reg.audit_rows() if r.object == uid
                     and r.action == "run analysis result"]
            assert trail and REASON in str(trail[-1].detail)
            revisions = reg.revisions(first.number)
            assert [r.withdrawn_utc is not None for r in revisions] == [True, False]
        ref = _entries(case.reference)
        for where, figures in _entries(result).items():
            for name, (value, _u) in figures.items():
                same, big_u = ref[where][name]
                print(f"{where} {name}: corrected {value:.7g}, reference {same:.7g}, "
                      f"|difference|/U {abs(value - same) / big_u:.4f}")
                if abs(value - same) > 0.01 * big_u:
                    off.append((where, name, value, same, big_u))
                worst = max(worst, abs(value - same) / big_u)
    print(f"largest |corrected - reference| over U: {worst:.4f}")
    assert not off, off


def test_the_correction_is_a_budget_row_and_u_grows_by_it(case: Case) -> None:
    """u(e) = U/2 with sensitivity 1 beside the reference's own terms: the combined
    standard uncertainty grows to sqrt(u_c^2 + u(e)^2), and U = k(nu_eff) times it by hand
    (docs/method.md A1, D1). U itself may fall: an infinite-dof term beside a Type A term
    of 2 dof raises nu_eff, and k(nu_eff) falls faster than u_c grows (seen: 4.5 -> 2.9)."""
    u_e = case.e_U_rel / 2.0
    run = case.runs[0]
    _, second = _reissued(run)
    result = json.loads((run / layout.ISSUED / second.number / layout.RESULT).read_text())
    ref = _rates(case.reference)
    for rate, entry in _rates(result).items():
        b = entry["rate_error_budget"]
        assert (b["timebase_correction_rel"], b["timebase_correction_ustd_rel"]) == \
            (case.e_rel, u_e)
        budget = next(x for x in entry["budgets"] if x["key"] == "rate_error_rel")
        row = next(t for t in budget["terms"] if "time-base correction" in t["quantity"])
        assert (row["estimate"], row["ustd"], row["sensitivity"], row["contribution_ustd"]) \
            == (case.e_rel, u_e, 1.0, u_e)
        assert budget["reproduces_reported_U"] is True
        rb = ref[rate]["rate_error_budget"]
        uc2 = rb["timing_ustd_rel"] ** 2 + rb["timebase_ustd_rel"] ** 2 \
            + rb["repeatability_ustd_rel"] ** 2
        nu = (uc2 + u_e ** 2) ** 2 / (rb["repeatability_ustd_rel"] ** 4
                                      / rb["repeatability_dof"])
        hand = coverage_factor(nu) * math.sqrt(uc2 + u_e ** 2)
        assert entry["rate_error_U_rel"] == pytest.approx(hand, rel=1e-3)
        before = next(x for x in ref[rate]["budgets"] if x["key"] == "rate_error_rel")
        assert budget["combined_ustd"] == pytest.approx(
            math.hypot(before["combined_ustd"], u_e), rel=1e-9)
        assert budget["combined_ustd"] > before["combined_ustd"]
        print(f"{rate:+g} deg/s: u_c {before['combined_ustd']:.4g} -> "
              f"{budget['combined_ustd']:.4g} with u(e) {u_e:.3g}; nu_eff "
              f"{before['dof_eff']:.3g} -> {budget['dof_eff']:.3g}, k "
              f"{before['coverage_factor']:.3g} -> {budget['coverage_factor']:.3g}; U "
              f"{ref[rate]['rate_error_U_rel']:.4g} -> {entry['rate_error_U_rel']:.4g}")


def test_the_reissued_certificate_states_the_correction_and_why_and_r1_is_withdrawn(
        case: Case) -> None:
    run = case.runs[0]
    first, second = _reissued(run)
    folder = run / layout.ISSUED / second.number
    e_text, u_text = f"e = {case.e_rel:.3g}", f"U = {case.e_U_rel:.3g}, k = 2"
    html = re.sub(r"\s+", " ", (folder / "certificate.html").read_text())
    pdf = " ".join(_pages(folder / "certificate.pdf"))
    dcc = etree.parse(str(folder / "certificate.dcc.xml")).getroot()
    said = [" ".join(d.split()) for d in dcc.xpath(
        ".//dcc:statement[dcc:name/dcc:content='Corrections applied']/dcc:declaration/"
        "dcc:content/text()", namespaces=NS)]
    assert len(said) == 1, said
    for text in (html, pdf, said[0]):
        assert "Correction applied" in text
        assert f"serial {SERIAL}" in text and e_text in text and u_text in text
        assert f"Why: {REASON}" in text
        assert "as-found error of calibration C-2026-777" in text
    assert "Correction applied" not in " ".join(
        _pages(run / layout.ISSUED / first.number / "certificate.pdf"))
    done = cli("verify", str(run / layout.ISSUED / first.number / "certificate.dcc.xml"),
               "--register", case.url)
    assert f": withdrawn: certificate {first.number}" in done.stdout, done.stdout
    done = cli("verify", str(folder / "certificate.dcc.xml"), "--register", case.url)
    assert f": issued: certificate {second.number}" in done.stdout, done.stdout
    # the corrections file in the run folder is the one the registered result states
    stated = json.loads((run / "corrections.json").read_text())["corrections"]
    assert stated == json.loads((folder / layout.RESULT).read_text())["corrections"]
    assert [c["reason"] for c in stated] == [REASON]


def test_what_a_finding_asks_of_an_issue_without_a_run(tmp_path: Path) -> None:
    """corrections_due on register records alone (no run made): the correction a counter's
    recorded finding calls for, with its U; a finding without U, or an item found out
    with no correction model, refuses; a run registered after the finding, or timed by
    another counter, is not touched; a result that states the correction needs no second
    analysis; the certificate's words name the item, e with its U and why."""
    from bench.app.certificate.corrected import already_applied, corrections_due
    from bench.report.corrections import statements
    from bench.report.result_frame import corrections_of

    url = sqlite_register(tmp_path / "register")
    today = dt.date.today()
    counter = {"where": "axes.outer.counter", "item": "counter", "serial": SERIAL}
    fixture = {"where": "axes.outer.fixture", "item": "fixture", "serial": "FX-1"}
    with Register.open(url, migrate=False) as reg:
        quality = reg.authenticate(QUALITY, password(QUALITY), "quality")
        for serial in (SERIAL, OTHER, "FX-1"):
            reg.add_equipment(quality, serial, MODEL, "C-1", "Cal Lab",
                              today + dt.timedelta(days=300))
        uses = reg.register_run("uses-it", "b", None, "v", True, {}, [counter])
        other = reg.register_run("other", "b", None, "v", True, {},
                                 [{**counter, "serial": OTHER}])
        both = reg.register_run("with-fixture", "b", None, "v", True, {}, [counter, fixture])
        assert corrections_due(reg, uses) == ([], [])        # nothing recorded yet
        reg.update_equipment(quality, SERIAL, "C-2", "Cal Lab", today + dt.timedelta(400),
                             today, "out", 3e-7, None)
        due, refused = corrections_due(reg, uses)
        assert due == [] and len(refused) == 1 and "has no U" in refused[0]
        reg.update_equipment(quality, SERIAL, "C-3", "Cal Lab", today + dt.timedelta(400),
                             today, "out", 3e-7, 3e-8)
        due, refused = corrections_due(reg, uses)
        assert refused == [] and [(c.where, c.serial, c.quantity, c.value, c.U)
                                  for c in due] == \
            [("axes.outer.counter", SERIAL, "timebase_offset_rel", 3e-7, 3e-8)]
        assert corrections_due(reg, other) == ([], [])
        reg.update_equipment(quality, "FX-1", "C-2", "Cal Lab", today + dt.timedelta(400),
                             today, "out", 0.1, 0.01)
        assert "no correction model" in " ".join(corrections_due(reg, both)[1])
        later = dataclasses.replace(uses, registered_utc=(today + dt.timedelta(1))
                                    .isoformat() + "T00:00:00Z")
        assert corrections_due(reg, later) == ([], [])
    stated = msgspec.structs.asdict(due[0])
    applied = {"corrections": [{**stated, "reason": REASON}]}
    assert already_applied(json.dumps(applied), due) and not already_applied("{}", due) \
        and not already_applied(None, due)
    assert not already_applied(json.dumps({"corrections": [{**stated, "value": 2e-7}]}),
                               due)
    said = statements(corrections_of(applied))
    assert len(said) == 1 and f"serial {SERIAL}" in said[0] and "e = 3e-07" in said[0] \
        and "U = 3e-08, k = 2" in said[0] and said[0].endswith(f"Why: {REASON}.")
