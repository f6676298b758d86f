"""Issue 43: every U the demo certificate prints follows from the budget it prints (u_c from
the contributions, k from nu_eff by docs/method.md D1), the method text carries the code's
own formulas and rule, and every interval or limit the certificate prints is in the DCC as
the same coverage interval (docs/method.md D2), none "resolved" whose interval reaches 0.
"""

from __future__ import annotations

import html as html_lib
import math
import re
from decimal import Decimal
from typing import Any

import pytest
from lxml import etree

from bench.analysis.coverage import (
    COVERAGE_FORMULA,
    COVERAGE_RULE,
    coverage_factor,
)
from bench.analysis.turns import RATE_ERROR_U_FORMULA, REPEATABILITY_FORMULA
from bench.report.certificate.rounding import RESOLUTION_RULE
from tests.conftest import ROOT, DemoRun

MINUS = "\u2212"
NS = {"dcc": "https://ptb.de/dcc", "si": "https://ptb.de/si"}


def _flat(text: str) -> str:
    return " ".join(text.split())


def _number(text: str) -> float:
    return float(text.replace(MINUS, "-").replace("e−", "e-").strip())


def _decimals(text: str) -> int:
    """Decimal places of a printed number (negative exponent counted for 1.96e-08)."""
    d = Decimal(text.replace(MINUS, "-").replace("e−", "e-"))
    return -int(d.as_tuple().exponent)


def _tables(html: str) -> list[tuple[str, list[list[str]], str]]:
    """(caption, body rows, the notes after the table) of every captioned table."""
    out = []
    for m in re.finditer(r'<div class="caption">(.*?)</div><table[^>]*>(.*?)</table>'
                         r'((?:\s*<p class="tnote">.*?</p>)*)', html, flags=re.S):
        body = m.group(2).split("<tbody>")[-1]
        rows = [[html_lib.unescape(re.sub(r"<[^>]+>", "", c)).strip()
                 for c in re.findall(r"<td[^>]*>(.*?)</td>", tr, flags=re.S)]
                for tr in re.findall(r"<tr>(.*?)</tr>", body, flags=re.S)]
        notes = html_lib.unescape(re.sub(r"<[^>]+>", " ", m.group(3)))
        head = " | ".join(re.findall(r"<th[^>]*>(.*?)</th>", m.group(2), flags=re.S))
        out.append((html_lib.unescape(m.group(1)), rows, html_lib.unescape(head) + "\n"
                    + notes))
    return out


@pytest.fixture(scope="module")
def cert(demo_run: DemoRun) -> dict[str, Any]:
    html = (demo_run.dir / "certificate.html").read_text(encoding="utf-8")
    return {"html": html, "tables": _tables(html), "result": demo_run.result,
            "dcc": etree.parse(str(demo_run.dir / "certificate.dcc.xml")).getroot()}


def test_the_method_text_carries_the_code_s_formulas_and_rule() -> None:
    """docs/method.md and the shipped bench/method.md state D1/D2 word for word as the code
    computes and the certificate prints them."""
    shipped = (ROOT / "bench" / "method.md").read_text(encoding="utf-8")
    assert shipped == (ROOT / "docs" / "method.md").read_text(encoding="utf-8")
    flat = _flat(shipped)
    for text in (COVERAGE_FORMULA, COVERAGE_RULE, REPEATABILITY_FORMULA, RATE_ERROR_U_FORMULA,
                 RESOLUTION_RULE):
        assert _flat(text) in flat, text[:60]


def test_coverage_factor_is_ea_4_02_table_e1() -> None:
    # EA-4/02 M:2022 table E.1 (95.45 %)
    for nu, k in ((1, 13.97), (2, 4.53), (3, 3.31), (4, 2.87), (5, 2.65), (6, 2.52),
                  (7, 2.43), (8, 2.37), (10, 2.28), (20, 2.13), (50, 2.05), (None, 2.0)):
        assert coverage_factor(nu) == k
    assert coverage_factor(6.9) == 2.52     # nu_eff truncated to the next lower integer


def test_each_printed_u_recomputes_from_its_printed_budget(cert: dict[str, Any]) -> None:
    """Every annex budget: u_c = sqrt(sum of the printed u_i(y)^2), k = t_95.45 of the printed
    nu_eff, U = k u_c, equal to the printed U within the rounding shown."""
    seen = set()
    for caption, rows, notes in cert["tables"]:
        m = re.search(r"u_c = (\S+?)(?: \S+)?; ν_eff = (\S+); k = (\S+); U = (\S+?)[ ;]",
                      notes)
        if not m:
            continue
        seen.add(caption.split(",")[0])
        contributions = [r[5] for r in rows]
        lo = math.sqrt(sum(max(_number(c) - 0.5 * 10.0 ** -_decimals(c), 0) ** 2
                           for c in contributions))
        hi = math.sqrt(sum((_number(c) + 0.5 * 10.0 ** -_decimals(c)) ** 2
                           for c in contributions))
        nu_text, k_text, u_text = m.group(2), m.group(3), m.group(4)
        k = float(k_text)
        nu = None if nu_text == "∞" else float(nu_text)
        # nu_eff is printed to 0.1: its floor is the printed one's, or one less at x.0
        allowed = {coverage_factor(nu)} | ({coverage_factor(nu - 0.05)} if nu else set())
        assert k in allowed, (caption, nu_text, k_text)
        big_u = _number(u_text)      # two significant digits: half of the second
        half = 0.5 * 10.0 ** (math.floor(math.log10(big_u)) - 1)
        assert k * lo - half <= big_u <= k * hi + half, (caption, notes)
        # every term with finite dof shows it; a Type A repeatability carries its own
        if caption.startswith("rate error"):
            assert rows[0][6] != "∞" and nu is not None and k > 2.0
    for kind in ("rate error δ (relative)", "intra-turn instability σ",
                 "harmonic 1 amplitude a1 (relative)", "FOG scale k (eq. 5)",
                 "FOG bias ω0 (eq. 6)"):
        assert any(s.startswith(kind) for s in seen), kind


def test_the_results_print_the_budget_s_u(cert: dict[str, Any]) -> None:
    """The rate error's U in the results table (ppm) is the annex budget's U, and its k is
    the budget's; outer +10 deg/s: nu_eff 6 (pooled), k = 2.52."""
    budgets = {c: notes for c, _, notes in cert["tables"] if "ν_eff =" in notes}
    checked = 0
    for caption, rows, _ in cert["tables"]:
        m = re.match(r"Axis (\w+): per-turn rate error and instability", caption)
        if not m:
            continue
        for row in rows:
            rate = _number(row[0])
            key = f"rate error δ (relative), axis {m.group(1)}, {rate:+g} °/s"
            notes = next(v for c, v in budgets.items() if c.startswith(key))
            annex_u = _number(re.search(r"; U = (\S+?);", notes).group(1))
            printed_u = _number(row[3].split(" ± ")[1])
            assert printed_u == pytest.approx(annex_u * 1e6, rel=0.06), (row, notes)
            checked += 1
    assert checked == 10
    r = next(x for x in cert["result"]["axes"]["outer"]["rates"] if x["set_rate_dps"] == 10)
    assert r["rate_error_budget"]["coverage_factor"] == 2.52
    assert r["rate_error_budget"]["repeatability_dof"] == 6
    b = next(b for b in r["budgets"] if b["key"] == "rate_error_rel")
    assert b["coverage_factor"] == 2.52 and b["U_budget"] == pytest.approx(r["rate_error_u_rel"])


def _dcc_real(root: Any, qid: str) -> Any:
    q = root.find(f".//dcc:quantity[@id='{qid}']", NS)
    assert q is not None, qid
    return q.find("si:real", NS)


def _interval_of(real: Any) -> tuple[float, float, float] | None:
    mu = real.find("si:measurementUncertaintyUnivariate/si:coverageIntervalMU", NS)
    if mu is None:
        return None
    return tuple(float(mu.findtext(f"si:{t}", namespaces=NS))   # type: ignore[return-value]
                 for t in ("intervalMin", "intervalMax", "coverageProbability"))


def _rounds_to(x: float, text: str, down: bool) -> bool:
    q = Decimal(1).scaleb(-_decimals(text))
    got = Decimal(repr(x)).quantize(q, rounding="ROUND_FLOOR" if down else "ROUND_CEILING")
    return got == Decimal(text.replace(MINUS, "-"))


def test_every_interval_and_limit_printed_is_in_the_dcc(cert: dict[str, Any]) -> None:
    """σ of the per-turn rates (results table) and the floor-corrected intra-turn figures:
    an interval printed '[lo, hi]' is the DCC's coverageIntervalMU (95 %), a limit '< L' the
    DCC's [0, L] at 97.5 %; a printed interval never reaches 0."""
    root = cert["dcc"]
    found = {"interval": 0, "limit": 0}
    for caption, rows, notes in cert["tables"]:
        m = re.match(r"Axis (\w+): (per-turn rate error and instability|intra-turn "
                     r"instability std)", caption)
        if not m:
            continue
        axis = m.group(1)
        per_turn = m.group(2).startswith("per-turn")
        head = notes.splitlines()[0].split(" | ")
        unit = (head[4] if per_turn else head[3]).rsplit(", ", 1)[1]
        scale = 1e6 if unit == "ppm" else 100.0
        for row in rows:
            rate = _number(row[0])
            tok = f"{'m' if rate < 0 else 'p'}{abs(rate):g}"
            key = "rate_instability_rel" if per_turn else "intra_turn_instability_corrected_rel"
            cell = row[4] if per_turn else row[3]
            iv = _interval_of(_dcc_real(root, f"r_{axis}_{tok}_{key}"))
            if "[" in cell:
                lo_t, hi_t = re.search(r"\[(\S+), (\S+)\]", cell).groups()
                assert iv is not None and iv[2] == 0.95, (cell, iv)
                assert _rounds_to(iv[0] * scale, lo_t, down=True), (cell, iv)
                assert _rounds_to(iv[1] * scale, hi_t, down=False), (cell, iv)
                assert iv[0] > 0 and _number(lo_t) > 0, cell      # resolved: above zero
                found["interval"] += 1
            elif cell.startswith("< "):
                assert iv is not None and iv[0] == 0.0 and iv[2] == 0.975, (cell, iv)
                assert _rounds_to(iv[1] * scale * (1 - 1e-9), cell[2:], down=False), (cell, iv)
                found["limit"] += 1
    assert found["interval"] >= 4 and found["limit"] >= 4, found


def test_no_value_or_u_below_its_floor_in_the_stability_table(cert: dict[str, Any]) -> None:
    """The counter's 360 deg rows print σ as its interval or '< L', never 'σ ± U' below the
    timing floor (issue 43: '-200 | 360 | counter | 0.006 ± 0.017 | 0.021')."""
    rows = [r for c, rr, _ in cert["tables"] if "rate stability over" in c for r in rr
            if r[2] == "counter"]
    assert rows
    for r in rows:
        floor = _number(r[4])
        for cell in (r[3], r[5]):
            assert "±" not in cell, r
            if cell.startswith("< "):
                assert _number(cell[2:]) >= floor, r
            else:
                assert _number(re.search(r"\[(\S+),", cell).group(1)) > floor, r


def test_undetected_tones_are_limits_in_the_dcc(cert: dict[str, Any]) -> None:
    root = cert["dcc"]
    n = 0
    for lst in root.iterfind(".//dcc:list", NS):
        desc = lst.findtext("dcc:description/dcc:content", "", NS)
        if not desc.startswith("not significant"):
            continue
        for real in lst.iterfind(".//si:real", NS):
            if (real.findtext("si:label", "", NS) or "").endswith(("amplitude_rel",
                                                                   "amplitude_dps")):
                iv = _interval_of(real)
                assert iv is not None and iv[0] == 0.0 and iv[1] > 0, desc
                n += 1
    assert n > 0


def test_the_dcc_states_the_budget_s_k(cert: dict[str, Any]) -> None:
    real = _dcc_real(cert["dcc"], "r_outer_p10_rate_error_rel")
    mu = real.find("si:measurementUncertaintyUnivariate/si:expandedMU", NS)
    assert mu.findtext("si:coverageFactor", namespaces=NS) == "2.52"
    assert mu.findtext("si:coverageProbability", namespaces=NS) == "0.9545"

