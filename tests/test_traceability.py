"""Traceability: the counter's reference read back over SCPI, a false claim refused, the
calibration certificates and due dates from the stand file.

The driver talks to the counter twin over its real TCP channel; the twin answers
ROSCillator:SOURce? as the 53220A/53230A User's Guide says (AUTO at *RST: EXT when a valid
reference is at Ref In, else INT; selecting a source turns AUTO off). The refusal test runs
`bench run` on a twin stand whose counter has no reference wired while the stand file
claims one: exit 2, nothing measured, the key named.
"""

from __future__ import annotations

import datetime as dt
import json
import re
from pathlib import Path

import pytest

from bench.core.traceability import overdue, traced_items
from drivers.counter import Counter, CounterError
from sims.truth import AxisTruth
from tests.conftest import Twins, bench
from tests.counter_rig import AXIS, turning_stand

ROOT = Path(__file__).resolve().parents[1]
STAND = ROOT / "configs" / "stands" / "sim-two-axis.yaml"


@pytest.mark.parametrize("wired", [True, False])
def test_counter_reference_set_checked_and_read_back(wired: bool, twins: Twins) -> None:
    """The stand's claim is set (SENS:ROSC:SOUR EXT), the signal checked (EXT:CHEC ONCE)
    and read back; without a signal at Ext Ref In the counter refuses it (User's Guide)."""
    stand = turning_stand()
    twin = twins.counter(stand, AXIS, model="keysight-53230a",
                         truth=AxisTruth(counter_external_reference=wired))
    counter = twins.close_later(Counter.open(twin.resource, "keysight-53230a", stand.clock))
    if wired:
        assert counter.verify_reference("external", 1e-9) == "EXT"
        assert counter.readback["counter.reference"] == "EXT"
    else:
        with pytest.raises(CounterError):
            counter.verify_reference("external", 1e-9)
    assert counter.verify_reference("internal", None) == "INT"


def _mini(tmp: Path, stand_text: str) -> Path:
    (tmp / "stand.yaml").write_text(stand_text)
    proc = tmp / "mini.yaml"
    proc.write_text(f"""\
procedure: rate-ladder
title: reference check
stand: {tmp / 'stand.yaml'}
turns: 2
static_record_s: 2
prompts: false
axes:
  outer:
    rates_dps: [50]
""")
    return proc


@pytest.mark.timeout(120)
def test_claimed_external_reference_that_is_not_there_is_refused(tmp_path: Path) -> None:
    text = STAND.read_text()
    # the outer counter's Ext Ref In is left unconnected in the twin stand's truth
    first = text.index("counter_external_reference: true")
    text = text[:first] + "counter_external_reference: false" + text[first + 33:]
    proc = _mini(tmp_path, text)
    out = bench("run", str(proc), "--yes", "--out", str(tmp_path / "runs"), timeout=120)
    assert out.returncode == 2, out.stderr
    assert "Refused:" in out.stderr and "axes.outer.counter.reference:" in out.stderr
    run_dir = Path(out.stdout.strip().splitlines()[-1])
    events = [json.loads(x) for x in (run_dir / "events.jsonl").read_text().splitlines()]
    kinds = [e["event"] for e in events]
    assert "refused" in kinds and "acquire" not in kinds and "set_rate" not in kinds
    assert not (run_dir / "certificate.pdf").exists()


def test_calibrations_and_due_dates_from_the_stand_file() -> None:
    import yaml

    stand = yaml.safe_load(STAND.read_text())
    items = {t.where: t for t in traced_items(stand)}
    counter = items["axes.outer.counter"]
    assert counter.certificate == "SIM-CAL-53230A-0117"
    assert counter.due == dt.date(2027, 6, 30)
    assert "SI second" in counter.traces
    assert items["traceability[0]"].item.startswith("GPS-disciplined 10 MHz reference")
    assert items["traceability[0]"].stated_serial == "SIM-GPSDO-01"
    assert not items["axes.outer.fog"].stated
    assert overdue(stand, dt.date(2027, 1, 31)) == []
    late = overdue(stand, dt.date(2027, 2, 1))
    assert [t.where for t in late] == ["traceability[1]"]   # the slot sensors, due 01-31


@pytest.mark.timeout(120)
def test_past_due_warns_at_start_and_on_the_certificate(tmp_path: Path) -> None:
    text = STAND.read_text().replace("due: 2027-01-31", "due: 2020-01-31")
    proc = _mini(tmp_path, text)
    out = bench("run", str(proc), "--yes", "--out", str(tmp_path / "runs"), timeout=120)
    assert "WARNING: zero-mark slot sensors" in out.stdout + out.stderr
    assert "was due on 2020-01-31" in out.stdout + out.stderr
    run_dir = Path(out.stdout.strip().splitlines()[-1])
    html = (run_dir / "certificate.html").read_text(encoding="utf-8")
    flat = re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", html))
    assert "PAST DUE on the date of the work" in flat
    assert "SIM-CAL-53230A-0117" in flat
    # issue 46: a reference's stated serial in the serial column, said to be stated only
    from lxml import html as lxml_html
    table = next(t for t in lxml_html.fromstring(html).iter("table")
                 if "Serial (read back)" in t.text_content())
    rows = {" ".join(r[0].text_content().split()): " ".join(r[1].text_content().split())
            for r in table.iter("tr") if len(r) > 1 and r[0].tag == "td"}
    gps = next(v for k, v in rows.items() if k.startswith("GPS-disciplined 10 MHz reference"))
    assert gps == "SIM-GPSDO-01 (stated, not read back)", rows
    assert ("read back from the counter: external reference at Ext Ref In "
            "(SENS:ROSC:SOUR? EXT" in flat)


def test_serials_as_read_back_and_identities_that_do_not_single_an_instrument_out() -> None:
    from bench.core.traceability import identity_problems, serial_of, with_declared_serials

    idn = "Keysight Technologies,53230A,MY62000117,03.02-1519.2432; read back: x = 1"
    drive = "Bench CiA 402 drive, hw sim-1, sw 0.1.0, serial 41001; read back: 0x6091 = 1/1"
    fog = "KVH DSP-1760; format kvh-a; axis z; 1000 Hz; deg/s (set and read back)"
    assert serial_of(idn) == "MY62000117"          # *IDN? field 3 (IEEE 488.2)
    assert serial_of(drive) == "41001"             # identity object 0x1018:4
    assert serial_of(drive.replace("41001", "0")) is None     # 0: the maker set none
    assert serial_of(fog) is None
    ids = {"outer": {"counter": idn, "drive": drive, "fog": fog},
           "inner": {"counter": idn, "drive": drive.replace("41001", "0"), "fog": fog,
                     "counter_reference": "external reference at Ext Ref In"}}
    assert identity_problems(ids) == [
        "the fog of outer reported no serial number",
        "the drive of inner reported no serial number",
        "the fog of inner reported no serial number",
        "the counter of outer, counter of inner report one serial (MY62000117) of one maker: "
        "two instruments cannot share it"]
    stand = {"axes": {"outer": {"fog": {"serial": "1760-20231"}},
                      "inner": {"fog": {"serial": "1760-20232"}}}}
    declared = with_declared_serials(ids, stand)
    assert serial_of(declared["outer"]["fog"]) == "1760-20231"
    assert "as the stand file states" in declared["inner"]["fog"]
    assert not any("fog" in p for p in identity_problems(declared))


def test_budgets_combine_as_ea_4_02_says() -> None:
    """u_c = sqrt(sum (c_i u_i)^2); nu_eff by Welch-Satterthwaite; k = t_95.45(floor(nu_eff))
    to two decimals (EA-4/02 table E.1; hand-derived)."""
    from bench.report.budget import NORMAL, STUDENT_T, Budget, Term
    from bench.report.budget_codec import budget_from_json
    from bench.report.codec import encode

    b = Budget("y", "y", "1", 1.0, (Term("a", 1.0, 3.0, STUDENT_T, 1.0, 4.0),
                                     Term("b", 0.0, 2.0, NORMAL, -2.0, None)), 10.45)
    assert b.ustd == 5.0                              # sqrt(3^2 + 4^2)
    assert b.dof_eff == 5.0 ** 4 / (3.0 ** 4 / 4.0)   # only the Type A term has finite dof
    assert b.k == 2.09                                # nu_eff 30.9 -> t_95.45(30) = 2.087
    assert b.U == pytest.approx(10.45) and b.reproduces is True
    assert budget_from_json(encode(b.record())) == b
