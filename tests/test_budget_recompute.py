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
    timing floor (issue 43: '-200 | 360 | counter | 0.006 ± 0.017 | 0.021'); the FOG's 1 and
    10 deg rows print the measured figure 'value ± U' only when value − U is above the FOG's
    floor over the window, else '< L' (L = value + U, never below the floor), and the DCC
    states the same limit as [0, L] (docs/method.md D2)."""
    tables = [(c, rr) for c, rr, _ in cert["tables"] if "rate stability over" in c]
    rows = [r for _, rr in tables for r in rr if r[2] == "counter"]
    assert rows
    for r in rows:
        floor = _number(r[4])
        for cell in (r[3], r[5]):
            assert "±" not in cell, r
            if cell.startswith("< "):
                assert _number(cell[2:]) >= floor, r
            else:
                assert _number(re.search(r"\[(\S+),", cell).group(1)) > floor, r
    limits = 0
    for caption, rr in tables:
        axis = caption.split()[1].rstrip(":")
        for r in rr:
            if r[2] != "FOG":
                continue
            floor, cell = _number(r[4]), r[3].rstrip("*")
            rate = _number(r[0])
            real = _dcc_real(cert["dcc"], f"r_{axis}_{'m' if rate < 0 else 'p'}{abs(rate):g}"
                                          f"_avg_{r[1]}_instability_rel")
            if "±" in cell:
                v, u = (_number(x) for x in cell.split(" ± "))
                assert v - u > floor, r
                assert _interval_of(real) is None
            else:
                assert cell.startswith("< ") and _number(cell[2:]) >= floor, r
                iv = _interval_of(real)
                assert iv is not None and iv[0] == 0.0 and iv[2] == 0.97725, r
                big_l, step = _number(cell[2:]), 10.0 ** (math.floor(math.log10(
                    _number(cell[2:]))) - 1)           # L rounded up to two digits
                assert 0 <= big_l - iv[1] * 1e6 < step + 1e-9, (r, iv)
                limits += 1
    assert limits > 0


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



# -- the drift-pulse certificate (docs/method.md B, D1) ---------------------------------------

@pytest.fixture(scope="module")
def drift_cert(drift_demo_run: DemoRun) -> dict[str, Any]:
    html = (drift_demo_run.dir / "certificate.html").read_text(encoding="utf-8")
    return {"html": html, "tables": _tables(html), "result": drift_demo_run.result,
            "dcc": etree.parse(str(drift_demo_run.dir / "certificate.dcc.xml")).getroot()}


def _annex(tables: list[tuple[str, list[list[str]], str]]
           ) -> dict[str, tuple[list[list[str]], str, dict[str, str]]]:
    """caption -> (rows, notes, printed u_c / nu_eff / k / U) of every annex budget."""
    out = {}
    for caption, rows, notes in tables:
        m = re.search(r"u_c = (\S+?)(?: \S+)?; ν_eff = (\S+); k = (\S+); U = (\S+?)[ ;]", notes)
        if m:
            out[caption] = (rows, notes, dict(zip(("uc", "nu", "k", "U"), m.groups(),
                                                  strict=True)))
    return out


def _signed(row: list[str]) -> float:
    """c_i u(x_i) from the printed c_i and u(x_i) (three significant digits each)."""
    return _number(row[4]) * _number(row[2])


def test_each_printed_drift_u_recomputes_from_its_printed_budget(
        drift_cert: dict[str, Any]) -> None:
    """Every drift budget of the annex: u_c² = Σ (c_i u(x_i))² + 2 Σ r c_i u(x_i) c_j u(x_j)
    (GUM 5.2.2, the correlations its note names), k = t_95.45 of the printed ν_eff, U = k u_c,
    equal to the printed U within the rounding shown (docs/method.md D1: one rule, no k = 2
    exception for part B)."""
    annex = _annex(drift_cert["tables"])
    kinds = {c.split(" (")[0].split(",")[0] for c in annex}
    assert kinds >= {"own drift ω_own", "apparent drift ω_app at 0°", "platform azimuth A",
                     "horizontal Earth rate W_h from the apparent drifts"}, kinds
    for caption, (rows, notes, p) in annex.items():
        s = [_signed(r) for r in rows]
        var = sum(x * x for x in s)
        for i, j, r in re.findall(r"r\(row (\d+), row (\d+)\) = (\S+?);", notes):
            var += 2 * float(r) * s[int(i) - 1] * s[int(j) - 1]
        uc = math.sqrt(var)
        assert uc == pytest.approx(_number(p["uc"]), rel=5e-3), (caption, notes)
        nu = None if p["nu"] == "∞" else float(p["nu"])
        k = float(p["k"])
        assert k in {coverage_factor(nu)} | ({coverage_factor(nu - 0.05)} if nu else set())
        assert nu is not None and k > 2.0, caption       # Type A rows with finite dof
        big_u = _number(p["U"])
        half = 0.5 * 10.0 ** (math.floor(math.log10(big_u)) - 1)
        assert abs(k * uc - big_u) <= half + 5e-3 * big_u, (caption, notes)


def test_the_drift_budgets_list_the_quantities_themselves(drift_cert: dict[str, Any]) -> None:
    """Inputs are quantities with their estimates and units, not effects (x_i = 0, c_i = 1):
    the position means (Type A, ν = n − 1 = 9, c = ±1/2), k_as (2 V/deg, c = −w/k_as), and
    in the azimuth the X and Y k_as with r = 1, whose contributions cancel (a common scale
    does not turn A = atan2(−app_y, app_x)); hand-derived sensitivities from result.json."""
    annex = _annex(drift_cert["tables"])
    drift = drift_cert["result"]["drift"]
    for caption, (rows, _notes, _p) in annex.items():
        assert not all(_number(r[4]) == 1.0 for r in rows), caption
        kas = [r for r in rows if "k_as" in r[0]]
        assert kas and all(r[1] == "2.00000 V/deg" for r in kas), caption
        means = [r for r in rows if "mean drift at" in r[0]]
        assert means and all(r[3] == "Student t" and r[6] == "9" for r in means), caption
        if caption.startswith(("own drift", "apparent drift")):
            axis = re.search(r"\((\w)\)", caption).group(1)
            w = drift["axes"][axis]["own_dph" if caption.startswith("own") else "apparent_dph"]
            assert _number(kas[0][4]) == pytest.approx(-w / 2.0, rel=3e-3), caption
            sign = -1 if caption.startswith("apparent") else 1
            assert [_number(r[4]) for r in means] == [0.5, 0.5 * sign], caption
    rows, notes, _ = next(v for c, v in annex.items() if c.startswith("platform azimuth A"))
    x, y = (drift["axes"][g]["apparent_dph"] for g in "xy")
    r2 = x * x + y * y
    i, j = (int(n) - 1 for n in re.search(r"r\(row (\d+), row (\d+)\) = 1;", notes).groups())
    assert "k_as (x)" in rows[i][0] and "k_as (y)" in rows[j][0]
    assert _signed(rows[i]) + _signed(rows[j]) == pytest.approx(0.0, abs=1e-3 * abs(
        _signed(rows[i])))
    x0 = next(r for r in rows if r[0].startswith("X: mean drift at 0°"))
    assert _number(x0[4]) == pytest.approx(0.5 * math.degrees(1.0) * y / r2, rel=3e-3)
    turn = next(r for r in rows if "platform turn" in r[0])
    assert _number(turn[4]) == 0.5                 # one turn rotates A by e / 2


def test_every_printed_drift_u_is_its_budget_s(drift_cert: dict[str, Any]) -> None:
    """The results table's, the azimuth's and the Earth-rate check's U are their annex
    budget's U, and the DCC states each with the budget's k (si:coverageFactor)."""
    annex = {c: p for c, (_, _, p) in _annex(drift_cert["tables"]).items()}

    def budget_u(prefix: str) -> float:
        return _number(next(p["U"] for c, p in annex.items() if c.startswith(prefix)))

    rows = next(rr for c, rr, _ in drift_cert["tables"] if c.startswith("Own and apparent"))
    for r in rows:
        assert _number(r[1].split(" ± ")[1]) == budget_u(f"own drift ω_own ({r[0]})")
        assert _number(r[3].split(" ± ")[1]) == budget_u(f"apparent drift ω_app at 0° ({r[0]})")
    flat = _flat(html_lib.unescape(re.sub(r"<[^>]+>", " ", drift_cert["html"])))
    az = re.search(r"Platform azimuth \(X input axis\) ± U (\S+) ± (\S+) °", flat)
    assert _number(az.group(2)) == budget_u("platform azimuth A")
    wh = re.search(r"Horizontal Earth rate from the apparent drifts (\S+) ± (\S+) °/h", flat)
    assert _number(wh.group(2)) == budget_u("horizontal Earth rate W_h")
    drift = drift_cert["result"]["drift"]
    for qid, node, stem in (("drift_x_own_dph", drift["axes"]["x"], "own"),
                            ("drift_azimuth_deg", drift, "azimuth")):
        mu = _dcc_real(drift_cert["dcc"], qid).find(
            "si:measurementUncertaintyUnivariate/si:expandedMU", NS)
        k = node[f"{stem}_coverage_factor"]
        assert k > 2.0 and mu.findtext("si:coverageFactor", namespaces=NS) == f"{k:.2f}"


# -- issue 56: every printed statement recomputable --------------------------------------------

def _recomputed(rows: list[list[str]], notes: str) -> tuple[float, float | None]:
    """(u_c, nu_eff) from a printed budget alone: u_c² = Σ (c_i u(x_i))² + 2 Σ r c_i u(x_i)
    c_j u(x_j) over the correlations its note names (GUM 5.2.2), nu_eff = u_c⁴ / Σ
    (u_i(y)⁴ / ν_i) with that u_c (docs/method.md D1); None for infinite."""
    s = [_signed(r) for r in rows]
    var = sum(x * x for x in s)
    for i, j, r in re.findall(r"r\(row (\d+), row (\d+)\) = (\S+?);", notes):
        var += 2 * float(r) * s[int(i) - 1] * s[int(j) - 1]
    uc = math.sqrt(var)
    denom = sum(_number(r[5]) ** 4 / float(r[6]) for r in rows if r[6] != "∞")
    return uc, (uc ** 4 / denom if denom > 0 else None)


def _check_recomputes(annex: dict[str, tuple[list[list[str]], str, dict[str, str]]]) -> int:
    """Each budget's printed u_c, nu_eff, k and U from its printed rows (issue 56 item 1:
    the correlation is in nu_eff's numerator too)."""
    n = 0
    for caption, (rows, notes, p) in annex.items():
        uc, nu = _recomputed(rows, notes)
        assert uc == pytest.approx(_number(p["uc"]), rel=6e-3, abs=1e-300), (caption, notes)
        printed_nu = None if p["nu"] == "∞" else float(p["nu"])
        if nu is None or nu > 1e4:
            assert printed_nu is None or printed_nu > 1e4, (caption, nu)
        else:
            assert printed_nu == pytest.approx(nu, rel=0.03, abs=0.06), (caption, nu, notes)
        k = float(p["k"])
        allowed = {coverage_factor(nu)} | ({coverage_factor(nu * 0.97), coverage_factor(
            nu * 1.03)} if nu else set())
        assert k in allowed, (caption, nu, k)
        big_u = _number(p["U"])
        half = 0.5 * 10.0 ** (math.floor(math.log10(big_u)) - 1)
        assert abs(k * uc - big_u) <= half + 6e-3 * big_u, (caption, notes)
        n += 1
    return n


def test_every_printed_u_nu_and_k_recompute_with_correlations(
        cert: dict[str, Any], drift_cert: dict[str, Any]) -> None:
    """The demo's and the drift demo's annex budgets, mains ripple and FOG bias drift
    included: u_c, nu_eff (Welch-Satterthwaite with the correlated u_c) and k = t_95.45 of
    it, and U = k u_c, from what is printed (issue 56 items 1-2). The drift demo's azimuth
    (k_as of X and Y, r = 1, cancelling): nu_eff 33.9 and k 2.08, as docs/method.md D1 says."""
    demo, drift = _annex(cert["tables"]), _annex(drift_cert["tables"])
    kinds = {c.split(",")[0] for c in demo}
    assert {"mains ripple amplitude (deg/s)", "mains ripple phase",
            "FOG bias drift during the pair (A3)"} <= kinds, kinds
    assert _check_recomputes(demo) >= 100 and _check_recomputes(drift) >= 6
    _, _, az = next(v for c, v in drift.items() if c.startswith("platform azimuth A"))
    assert (az["nu"], az["k"]) == ("33.9", "2.08")
    # the results print the mains' and the bias drift's U as their budgets'
    mains = {c: p for c, (_, _, p) in demo.items() if c.startswith("mains ripple amplitude")}
    table = next(rr for c, rr, _ in cert["tables"] if c.startswith("Axis outer: mains"))
    for row in table:
        if "±" in row[2]:
            key = next(c for c in mains if c.endswith(f"outer, {_number(row[0]):+g} °/s: "
                                                      f"estimate {c.split('estimate ')[1]}"))
            assert _number(row[2].split(" ± ")[1]) == _number(mains[key]["U"]), row
    drifts = {c: p for c, (_, _, p) in demo.items() if c.startswith("FOG bias drift")}
    pairs = next(rr for c, rr, _ in cert["tables"] if c.startswith("Axis outer: FOG cross"))
    for row in pairs:
        key = next(c for c in drifts if f"axis outer, pair {row[0]} °/s" in c)
        assert _number(row[4].split(" ± ")[1]) == _number(drifts[key]["U"]), (row, key)


def _budget_of(entry: dict[str, Any], key: str) -> dict[str, Any] | None:
    return next((b for b in entry.get("budgets", []) if b["key"] == key), None)


def _tok(rate_text: str) -> str:
    rate = _number(rate_text)
    return f"{'m' if rate < 0 else 'p'}{abs(rate):g}"


def _is_the_dcc_s_limit(root: Any, qid: str, cell: str, scale: float, limit: float,
                        probability: float) -> None:
    """The DCC states the certificate's '< L' as [0, L] at its one-sided level, L the
    analysis's (to the double), and the printed L is it rounded up."""
    iv = _interval_of(_dcc_real(root, qid))
    assert iv is not None and iv[0] == 0.0, (qid, iv)
    assert iv[1] == pytest.approx(limit, rel=1e-12) and iv[2] == pytest.approx(probability,
                                                                                abs=1e-12)
    assert _rounds_to(iv[1] * scale * (1 - 1e-9), cell[2:], down=False), (qid, cell, iv)


def test_every_interval_and_limit_follows_the_one_rule(cert: dict[str, Any]) -> None:
    """Issue 56 item 3, on the demo certificate: a tone is 'a ± U' only when a − c·u(a) > 0
    (u(a) its budget's u_c, c the joint test's radius printed in the note) and '< L' with
    L ≥ a + c·u(a) otherwise; the raw intra-turn instability is 'raw ± U' only when raw − U
    lies above the FOG floor, '< L' (L ≥ raw + U, ≥ the floor) otherwise."""
    result = cert["result"]
    seen = {"tone ±": 0, "tone <": 0, "raw <": 0}
    for caption, rows, notes in cert["tables"]:
        m = re.match(r"Axis (\w+): (systematic intra-turn|mains-frequency|intra-turn "
                     r"instability std)", caption)
        if not m:
            continue
        entries = {e["set_rate_dps"]: e for e in result["axes"][m.group(1)]["rates"]}
        what = m.group(2)
        for row in rows:
            e = entries[_number(row[0])]
            if what == "intra-turn instability std":
                raw, big_u = e["intra_turn_instability_rel"], e["intra_turn_instability_U_rel"]
                floor = e["intra_turn"]["floor_rel"]
                # the budget adds the FOG scale's share (1e-6 of it) to the printed U
                assert big_u == pytest.approx(_budget_of(e, "intra_turn_instability_rel")[
                    "U_budget"], rel=1e-5)
                if row[1].startswith("< "):
                    assert raw - big_u <= floor, row
                    assert _number(row[1][2:]) / 100 >= max(raw + big_u, floor) * (1 - 1e-9)
                    _is_the_dcc_s_limit(cert["dcc"], f"r_{m.group(1)}_{_tok(row[0])}_intra_"
                                        "turn_instability_rel", row[1], 100.0,
                                        e["intra_turn"]["raw_upper_rel"], 0.97725)
                    seen["raw <"] += 1
                else:
                    assert raw - big_u > floor, row
                continue
            c = float(re.search(r"\(c = ([\d.]+)", notes).group(1)) if "systematic" in what \
                else None
            if what.startswith("systematic"):
                h = e["systematic"]["harmonics"][int(row[1]) - 1]
                b = _budget_of(e, f"systematic.harmonics[{int(row[1]) - 1}].amplitude_rel")
                a, scale, cell = h["amplitude_rel"], 100.0, row[2]
                c = h["interval_factor"]
            else:
                mains = e["systematic"]["mains"]
                b = _budget_of(e, "systematic.mains.amplitude_dps")
                a, scale, cell = mains["amplitude_dps"], 1.0, row[2]
                c = mains["interval_factor"]
            assert b is not None and c is not None and c > 2.0, row
            lower, upper = a - c * b["combined_ustd"], a + c * b["combined_ustd"]
            if cell.startswith("< "):
                assert lower <= 0, (caption, row)
                assert _number(cell[2:]) >= upper * scale * (1 - 1e-9), (caption, row)
                assert row[-1] == "—"
                qid = (f"r_{m.group(1)}_{_tok(row[0])}_h_{row[1]}_amplitude_rel"
                       if what.startswith("systematic") else
                       f"r_{m.group(1)}_{_tok(row[0])}_mains_amplitude_dps")
                _is_the_dcc_s_limit(cert["dcc"], qid, cell, scale, upper,
                                    1 - math.exp(-c * c / 2))
                seen["tone <"] += 1
            else:
                assert lower > 0, (caption, row)
                assert _number(cell.split(" ± ")[1]) == pytest.approx(
                    b["U_budget"] * scale, rel=0.06), (caption, row)
                seen["tone ±"] += 1
    assert all(seen.values()), seen
    # the printed c is the joint test's radius for the tones tested: sqrt(-2 ln alpha_1)
    note = next(n for c_, _, n in cert["tables"] if "systematic intra-turn" in c_)
    c_text = float(re.search(r"\(c = ([\d.]+)", note).group(1))
    alpha_1 = 1 - 0.95 ** (1 / 4)
    assert c_text == pytest.approx(math.sqrt(-2 * math.log(alpha_1)), abs=0.005)


def _dcc_intervals(root: Any) -> list[tuple[str, tuple[float, float, float], float]]:
    out = []
    for real in root.iterfind(".//si:real", NS):
        mu = real.find("si:measurementUncertaintyUnivariate/si:coverageIntervalMU", NS)
        label = real.findtext("si:label", "", NS)
        if mu is None or not label:
            continue
        out.append((label, _interval_of(real),
                    float(mu.findtext("si:valueStandardMU", namespaces=NS))))
    return out


def test_the_dcc_s_standard_uncertainty_of_each_interval_is_its_budget_s(
        cert: dict[str, Any]) -> None:
    """Issue 56 item 4: beside each coverage interval the DCC states the figure's own
    standard uncertainty: its budget's u_c (raw intra-turn, tones), s/√(2(N−1)) for σ of
    the per-turn rates, U/k for the FOG's figures over an angle, the Monte Carlo's standard
    deviation for a floor-corrected figure; never (max − min)/4. Its [0, L] intervals are
    exactly the figures the analysis did not resolve."""
    result = cert["result"]
    kinds: dict[str, int] = {}
    for label, (lo, hi, _p), ustd in _dcc_intervals(cert["dcc"]):
        m = re.match(r"axes\.(\w+)\.rates\[(\d+)\]\.(.+)$", label)
        assert m, label
        e = result["axes"][m.group(1)]["rates"][int(m.group(2))]
        key = m.group(3)
        budget = _budget_of(e, key)
        if budget is not None:
            want, resolved = budget["combined_ustd"], None
            if key == "intra_turn_instability_rel":
                resolved = e["intra_turn"]["raw_resolved"]
            elif key.endswith(("amplitude_rel", "amplitude_dps")):
                tone = (e["systematic"]["mains"] if "mains" in key else
                        e["systematic"]["harmonics"][int(re.search(r"\[(\d+)\]",
                                                                   key).group(1))])
                resolved = tone["detected"]
        elif key == "rate_instability_rel":
            want, resolved = e["rate_instability_ustd_rel"], e["rate_instability_resolved"]
            assert want == pytest.approx(e["rate_instability_rel"] / math.sqrt(
                2 * (e["turns"] - 1)), rel=1e-12)
        elif key == "intra_turn_instability_corrected_rel":
            want, resolved = e["intra_turn"]["corrected_ustd_rel"], e["intra_turn"]["resolved"]
        else:
            a = re.match(r"intra_turn\.averaged\[(\d+)\]\.(instability_rel|corrected_rel)$",
                         key)
            assert a, label
            avg = e["intra_turn"]["averaged"][int(a.group(1))]
            if a.group(2) == "instability_rel":
                want, resolved = avg["ustd_rel"], avg["measured_resolved"]
                assert want == pytest.approx(avg["u_rel"] / coverage_factor(avg["dof"]))
            else:
                want, resolved = avg["corrected_ustd_rel"], avg["resolved"]
        assert want is not None and want > 0 and ustd == want, (label, ustd, want)
        assert ustd != pytest.approx((hi - lo) / 4.0, rel=1e-3), label
        assert resolved is not None and (lo == 0.0) == (not resolved), (label, lo, resolved)
        kinds[key.split(".")[-1]] = kinds.get(key.split(".")[-1], 0) + 1
    assert {"rate_instability_rel", "intra_turn_instability_rel", "amplitude_rel",
            "amplitude_dps", "intra_turn_instability_corrected_rel", "instability_rel",
            "corrected_rel"} <= set(kinds), kinds


def test_the_station_page_states_what_the_certificate_states(
        cert: dict[str, Any], demo_run: DemoRun) -> None:
    """Issue 56 item 6: the station's run page prints σ of the per-turn rates by the same
    rule as the certificate (its interval or '< L', never 'σ ± U'), and its note states
    k from ν_eff, not 'coverage factor 2'."""
    from bench.app.station.view import U_NOTE, final_view

    view = final_view(demo_run.dir)
    assert view is not None
    assert "coverage factor 2" not in U_NOTE and "ν_eff" in U_NOTE
    compared = 0
    for table in view[1]:
        if not str(table["id"]).startswith("rates-"):
            continue
        axis = str(table["id"])[len("rates-"):]
        unit = str(table["header"][3]).rsplit(", ", 1)[1]
        printed = next(rr for c, rr, _ in cert["tables"]
                       if c.startswith(f"Axis {axis}: per-turn rate error"))
        for row in table["rows"]:
            cell = row["cells"][3]
            assert "±" not in cell, cell
            assert cell.startswith("< ") or re.fullmatch(r"\S+ \[\S+, \S+\]", cell), cell
            if unit == "ppm":
                cert_row = next(r for r in printed if r[0] == row["cells"][0]
                                .replace("-", MINUS).replace("+", "+"))
                assert cell == cert_row[4], (cell, cert_row)
                compared += 1
    assert compared >= 10


def test_an_unresolved_raw_figure_is_judged_on_its_limit(cert: dict[str, Any]) -> None:
    """Issue 56 item 3 in conformity: a raw intra-turn figure not above the FOG floor is
    stated '< L' in the results, so a tolerance judges L (docs/method.md D2, the rule for
    limits): pass when L is within it, not assessed when not; never 'value ± U'."""
    from procedures.rate_ladder.analysis import raw_limit_check
    from procedures.rate_ladder.codec import ladder_of

    e = cert["result"]["axes"]["outer"]["rates"][0]
    assert e["intra_turn"]["raw_resolved"] is False
    entry = ladder_of(cert["result"]).axes["outer"].rates[0]
    big_l = e["intra_turn"]["raw_upper_rel"]
    assert big_l == max(e["intra_turn_instability_rel"] + e["intra_turn_instability_U_rel"],
                        e["intra_turn"]["floor_rel"])
    ok = raw_limit_check("outer", 10.0, entry, big_l * 1.01, "guard-band")
    assert (ok.verdict, ok.one_sided, ok.upper_rel, ok.floor_name) == (
        "pass", True, big_l, "FOG floor")
    na = raw_limit_check("outer", 10.0, entry, big_l * 0.99, "simple")
    assert na.verdict == "not-assessed" and "FOG floor" in na.reason
