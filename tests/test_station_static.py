"""The station view as a new user meets it after a run (issue 46, "the first hour"): a
finished run's page read without JavaScript, a refused run named refused with its first
cause, and a finished run's page in a browser showing how the run ended, not a live view
gone stale.

Real runs only: the shared demo run (tests/conftest.py demo_run, copied) and a run that
`bench run` refuses at start because the stand file claims an external reference the
counter twin does not have (as tests/test_traceability.py makes it). Pages are fetched
from a served instance (`bench serve`, waitress) over HTTP with urllib, which runs no
script, and read with the standard library's HTML parser.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import pytest

from bench.app.station.app import StationSettings, create_app
from bench.app.station.live import ending, run_status
from bench.core.events import decode_all
from tests.conftest import CONFIGS, DemoRun, bench, unavailable
from tests.test_station import (
    ARTIFACTS,
    TOKEN,
    _browser,
    _chromium,
    _start_server,
    _stop,
    _wait,
    assert_finished_page,
    assert_printed,
)

MINUS = "\u2212"


# -- the HTML as a reader without JavaScript gets it ----------------------------------------

class Page(HTMLParser):
    """The text of every element with an id, and every table's rows of cell texts."""

    def __init__(self, html: str) -> None:
        super().__init__(convert_charrefs=True)
        self.text: dict[str, str] = {}
        self.attrs_of: dict[str, dict[str, str | None]] = {}
        self.tables: dict[str, list[list[str]]] = {}
        self.headers: dict[str, list[str]] = {}
        self._open: list[tuple[str, str | None]] = []    # (tag, id) of open elements
        self._table: str | None = None
        self._row: list[str] | None = None
        self._cell: list[str] | None = None
        self.feed(html)

    VOID = {"meta", "link", "input", "br", "img", "hr"}

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        ident = a.get("id")
        if ident:
            self.attrs_of[ident] = a
            self.text.setdefault(ident, "")
        if tag in self.VOID:
            return
        self._open.append((tag, ident))
        if tag == "table":
            self._table = ident or f"table{len(self.tables)}"
            self.tables[self._table] = []
        elif tag == "tr" and self._table:
            self._row = []
        elif tag in ("td", "th") and self._row is not None:
            self._cell = []

    def handle_endtag(self, tag: str) -> None:
        if tag in self.VOID:
            return
        while self._open:
            open_tag, _ = self._open.pop()
            if open_tag == tag:
                break
        if tag in ("td", "th") and self._cell is not None and self._row is not None:
            self._row.append("".join(self._cell).strip())
            self._cell = None
        elif tag == "tr" and self._row is not None and self._table:
            in_head = any(t == "thead" for t, _ in self._open)
            if in_head:
                self.headers[self._table] = self._row
            else:
                self.tables[self._table].append(self._row)
            self._row = None
        elif tag == "table":
            self._table = None

    def handle_data(self, data: str) -> None:
        if self._cell is not None:
            self._cell.append(data)
        for _, ident in self._open:
            if ident:
                self.text[ident] = self.text.get(ident, "") + data


def get(port: int, path: str) -> tuple[int, str]:
    with urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=30) as resp:
        return resp.status, resp.read().decode("utf-8")


# -- the runs ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class Runs:
    folder: Path
    passed: Path
    result: dict[str, Any]
    refused: Path
    reason: str        # the refusal's message, as the engine journaled it


def _refused_run(tmp: Path, runs: Path) -> Path:
    """`bench run` on the twin stand with the outer counter's Ext Ref In left unconnected
    while the stand file claims it: valid input, refused at start, before anything moved."""
    text = (CONFIGS / "stands" / "sim-two-axis.yaml").read_text()
    claim = "counter_external_reference: true"
    first = text.index(claim)
    (tmp / "stand.yaml").write_text(text[:first] + "counter_external_reference: false"
                                    + text[first + len(claim):])
    proc = tmp / "refused.yaml"
    proc.write_text(f"procedure: rate-ladder\ntitle: refused at start\n"
                    f"stand: {tmp / 'stand.yaml'}\nturns: 2\nstatic_record_s: 2\n"
                    "prompts: false\naxes:\n  outer:\n    rates_dps: [50]\n")
    out = bench("run", str(proc), "--yes", "--out", str(runs), timeout=120)
    assert out.returncode == 2, out.stderr[-3000:]
    assert "Refused:" in out.stderr, out.stderr[-3000:]
    return Path(out.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def runs(demo_run: DemoRun, tmp_path_factory: pytest.TempPathFactory) -> Runs:
    assert demo_run.status == 0, demo_run.stderr[-3000:]
    tmp = tmp_path_factory.mktemp("station-static")
    passed = demo_run.copy_to(tmp / "runs")
    refused = _refused_run(tmp, tmp / "runs")
    events = [json.loads(x) for x in (refused / "events.jsonl").read_text().splitlines()]
    reason = next(e["reason"] for e in events if e["event"] == "refused")
    return Runs(tmp / "runs", passed, demo_run.result, refused, reason)


@pytest.fixture(scope="module")
def port(runs: Runs) -> Iterator[int]:
    proc, port = _start_server(runs.folder)
    yield port
    _stop(proc)


# -- without JavaScript -----------------------------------------------------------------------

def _scale(header: str) -> float:
    """The scale of a relative column from the unit its header names."""
    unit = header.rsplit(",", 1)[1].strip()
    return {"ppm": 1e6, "%": 100.0}[unit]


def test_a_finished_run_reads_without_javascript(runs: Runs, port: int) -> None:
    """The verdict, each pair's k and w0 and each rate's error with U, in the HTML the
    server sends, equal to result.json at the printed precision; the progress complete and
    the instruments' last state, no live "N s ago"."""
    status, html = get(port, f"/run/{runs.passed.name}")
    assert status == 200
    page = Page(html)
    result = runs.result
    assert page.text["status"] == "passed"
    assert page.text["verdict-text"] == str(result["verdict"]).upper() == "PASS"
    assert "no pair analysed yet" not in html
    checked = 0
    for axis, body in result["axes"].items():
        pairs = page.tables[f"pairs-{axis}"]
        assert len(pairs) == len(body["pairs"]) > 0
        head = page.headers[f"pairs-{axis}"]
        assert head == ["pair, deg/s", "k ± U", "ω0 ± U, deg/s"]
        for row, pair in zip(pairs, body["pairs"], strict=True):
            assert row[0] == f"±{pair['rate_dps']:g}"
            assert_printed(row[1].split(), pair["k"], pair["k_U"])
            assert_printed(row[2].replace("+", "").split(), pair["w0_dps"], pair["w0_U_dps"])
            checked += 1
        rates = page.tables[f"rates-{axis}"]
        head = page.headers[f"rates-{axis}"]
        scale = _scale(head[2])
        assert len(rates) == len(body["rates"])
        for row, rate in zip(rates, body["rates"], strict=True):
            assert float(row[0].replace(MINUS, "-")) == rate["set_rate_dps"]
            assert_printed(row[2].replace("+", "").split(), rate["rate_error_rel"] * scale,
                           rate["rate_error_U_rel"] * scale)
            assert row[4] == rate["verdict"].upper()
    assert checked == sum(len(b["pairs"]) for b in result["axes"].values())

    # how it ended: the plan completed, the bar full; the instruments' last state as times
    events = [json.loads(x) for x in (runs.passed / "events.jsonl").read_text().splitlines()]
    steps = next(e["steps"] for e in events if e["event"] == "plan")
    assert page.attrs_of["progress"]["value"] == "1.0000"
    assert page.text["step"] == f"Completed: all {steps} steps done; the run passed"
    assert page.text["health-title"] == "Instruments at the end of the run"
    assert " s ago" not in page.text["run"] and "STALE" not in page.text["run"]
    health = page.tables["health-table"]
    assert [r[0] for r in health] == list(result["axes"])
    assert all(len(c) == 19 and c[4] == "-" for r in health for c in (r[1], r[4], r[5])), \
        health      # each instrument last heard at a wall time, YYYY-MM-DD HH:MM:SS
    assert "controls" not in page.attrs_of          # nothing left to stop


def test_a_refused_run_reads_refused_with_its_first_cause(runs: Runs, port: int) -> None:
    _, html = get(port, "/")
    listed = Page(html)
    row = next(r for r in listed.tables["runs"] if r[0] == runs.refused.name)
    assert row[2] == f"refused {runs.reason}", row
    passed = next(r for r in listed.tables["runs"] if r[0] == runs.passed.name)
    assert passed[2] == "passed"

    _, html = get(port, f"/run/{runs.refused.name}")
    page = Page(html)
    assert page.text["status"] == "refused"
    assert page.text["step"] == f"Refused before anything moved: {runs.reason}"
    assert page.attrs_of["progress"]["value"] == "0.0000"
    assert "nothing was measured" in page.text["results-note"]
    assert f"refused - {runs.reason}" in page.text["log"]
    assert "exit with status 2 (refused)" in page.text["log"]
    assert "charts" in page.attrs_of and "hidden" in page.attrs_of["charts"]
    assert "controls" not in page.attrs_of

    _, body = get(port, "/api/runs")
    api = {r["run"]: r for r in json.loads(body)}
    assert api[runs.refused.name]["status"] == "refused"
    assert api[runs.refused.name]["cause"] == runs.reason
    assert api[runs.passed.name]["cause"] is None


# -- how a session ended, from hand-made journals ----------------------------------------------

def _exit(status: int, cause: str | None = None, later: list[str] | None = None
          ) -> dict[str, Any]:
    return {"event": "exit", "session": 1, "status": status, "cause": cause,
            "later": later or [], "utc": "2026-01-01T00:10:00+00:00"}


def test_each_ending_and_its_first_cause(tmp_path: Path) -> None:
    start = {"event": "session_start", "session": 1, "pid": 1}
    assert ending(decode_all([start]), tmp_path) is None
    assert ending(decode_all([start, _exit(0)]), tmp_path)["status"] == "passed"
    assert ending(decode_all([start, _exit(1)]), tmp_path)["status"] == "failed"
    end = ending(decode_all([start, _exit(3, "interrupted by SIGINT",
                                          ["drive outer: no answer"])]), tmp_path)
    assert end is not None
    assert (end["status"], end["cause"], end["later"]) == (
        "aborted", "interrupted by SIGINT", ["drive outer: no answer"])
    refused = {"event": "refused", "session": 1, "reason": "axes.outer.counter.reference: no"}
    end = ending(decode_all([start, refused, _exit(2)]), tmp_path)
    assert end is not None and (end["status"], end["cause"]) == ("refused", refused["reason"])
    # exit 3 without a cause: nothing went wrong at the bench; the outputs say what is missing
    end = ending(decode_all([start, _exit(3)]), tmp_path)
    assert end is not None and end["status"] == "incomplete"
    assert "no result.json" in end["cause"] and "bench analyze" in end["cause"]
    (tmp_path / "result.json").write_text('{"verdict": "incomplete"}')
    end = ending(decode_all([start, _exit(3)]), tmp_path)
    assert end is not None and "not every step" in end["cause"] and "--resume" in end["cause"]
    (tmp_path / "result.json").write_text('{"verdict": "pass"}')
    end = ending(decode_all([start, _exit(3)]), tmp_path)
    assert end is not None and "no certificate" in end["cause"]


def test_a_bench_gone_without_an_exit_is_stopped(tmp_path: Path) -> None:
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    st = run_status(decode_all([{"event": "session_start", "session": 1, "pid": gone.pid}]),
                    tmp_path)
    assert st["status"] == "stopped" and "--resume" in st["cause"]
    assert run_status([], tmp_path)["status"] == "created"


def test_what_the_files_say_is_escaped(tmp_path: Path) -> None:
    """A title or a refusal's message is text, never markup (the templates are *.html.j2,
    which Flask would not escape by itself)."""
    run = tmp_path / "runs" / "20260101-000000-x"
    run.mkdir(parents=True)
    (run / "procedure.yaml").write_text('title: "<script>alert(1)</script>"\n')
    (run / "stand.yaml").write_text("stand: {serial: S1}\n")
    (run / "events.jsonl").write_text("".join(json.dumps(e) + "\n" for e in [
        {"event": "session_start", "session": 1, "pid": 1, "utc": "2026-01-01T00:00:00+00:00"},
        {"event": "refused", "session": 1, "reason": "<img src=x onerror=alert(2)>"},
        _exit(2)]))
    client = create_app(StationSettings(tmp_path / "runs", TOKEN)).test_client()
    for path in ("/", f"/run/{run.name}"):
        html = client.get(path).get_data(as_text=True)
        assert "<script>alert" not in html and "<img src=x" not in html, path
        assert "&lt;img src=x onerror=alert(2)&gt;" in html, path


# -- in a browser ---------------------------------------------------------------------------

@pytest.mark.timeout(180)
def test_finished_and_refused_pages_in_a_browser(runs: Runs, port: int) -> None:
    """The script keeps what the server wrote: the end state stays after the page's live
    updates (the stream's state is drawn over it once a second)."""
    found = _chromium()
    if found is None:
        unavailable("chromium and chromium-driver are not installed (Debian packages "
                    "`chromium chromium-driver`; .ci/run installs them)")
    driver = _browser(found, height=1400)
    try:
        for run, how in ((runs.passed, "passed"), (runs.refused, "refused")):
            driver.get(f"http://127.0.0.1:{port}/run/{run.name}")
            _wait(lambda: (driver.execute_script("return window.station?.updates") or 0) >= 2,
                  30, "the page's first streamed update")
            assert_finished_page(driver, how)
            if how == "refused":
                assert runs.reason in driver.find_element("id", "step").text
            else:
                assert driver.find_element("id", "verdict-text").text == "PASS"
            time.sleep(1.5)                      # another update: still the end state
            assert_finished_page(driver, how)
            driver.save_screenshot(str(ARTIFACTS / f"finished-{how}.png"))
    finally:
        driver.quit()
