"""The station view (`bench serve`): live state read from run directories, its security
rules, and the page itself driven in a real headless browser during a simulated run.

The browser test needs Debian's chromium and chromium-driver (.ci/run installs them); it
is skipped, saying so, where they are missing. The one place a request is not real: a
request from a non-local address cannot be made on this sandboxed machine (no network
but loopback), so that rule is checked through Flask's WSGI test client with the remote
address set, and the server's refusal to bind another address without a token through
its argument parser.
"""

from __future__ import annotations

import argparse
import contextlib
import http.client
import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import msgspec
import numpy as np
import pytest
import yaml

from bench.app.station.app import StationSettings, create_app
from bench.app.station.live import (
    decimate,
    fog_trace,
    progress_of,
    turn_rates,
)
from bench.app.station.serve import settings_from_args
from bench.app.station.state import FogTrace
from bench.core.config import FogSettings
from bench.core.events import decode_all
from bench.core.journal_codec import tail_records
from drivers.fog_formats import get_format
from procedures.rate_ladder.events import HalfAcquired
from tests.conftest import CONFIGS, ROOT, bench_bg, cli, unavailable

TOKEN = "s3cret-token"
ARTIFACTS = Path(os.environ.get("BENCH_TEST_ARTIFACTS", ROOT / "test-artifacts")) / "station"


# -- the live state, from files, against hand-derived values ---------------------------

def _half(**fields: Any) -> HalfAcquired:
    """An `acquire` record as the ladder writes it, with the fields a test states."""
    return HalfAcquired(**{"axis": "outer", "unit": "outer/10dps", "half": 0,
                           "set_rate_dps": 10.0, "turns": 2, "edges_s": [0.0, 36.0, 72.0],
                           "counter_records": [0, 3], "fog_from": 0, "fog_to": 100,
                           "rate_hz": 1000.0, **fields})


def test_turn_rates_from_edges_hand_derived() -> None:
    # docs/method.md A1: w = 360 / T. Turn 1: T = 36 s -> 10 deg/s exactly; turn 2:
    # T = 36.000036 s -> 10 / (1 + 1e-6) deg/s, a deviation of -1/(1 + 1e-6) ppm.
    t = turn_rates(_half(axis="outer", edges_s=[5.0, 41.0, 77.000036], set_rate_dps=-10.0))
    assert t["rate_dps"][0] == pytest.approx(-10.0, rel=1e-15)
    assert t["rate_dps"][1] == pytest.approx(-10.0 / (1 + 1e-6), rel=1e-12)
    assert t["deviation_ppm"] == pytest.approx([0.0, -1 / (1 + 1e-6)], abs=1e-6)


def test_decimate_is_block_means() -> None:
    t = np.arange(10.0)
    y = np.array([1.0, 3.0] * 5)
    ts, ys = decimate(t, y, points=5)
    assert ts == [0.5, 2.5, 4.5, 6.5, 8.5] and ys == [2.0] * 5  # every-2nd would give 1.0


def test_progress_eta_from_measured_speed() -> None:
    # three steps of 100, 200, 300 s; the second started at bench t = 100 s and 40 bench
    # seconds have passed in it; 140 bench seconds took 14 wall seconds (speed 10).
    ev = [
        {"event": "plan", "steps": 3, "estimate_s": 600.0, "step_estimates_s": [100, 200, 300],
         "t_s": 0.0, "utc": "2026-01-01T00:00:00+00:00"},
        {"event": "step_start", "index": 0, "action": "a", "t_s": 0.0,
         "utc": "2026-01-01T00:00:00+00:00"},
        {"event": "step_done", "index": 0, "action": "a", "t_s": 100.0,
         "utc": "2026-01-01T00:00:10+00:00"},
        {"event": "step_start", "index": 1, "action": "b", "describe": "x", "t_s": 100.0,
         "utc": "2026-01-01T00:00:10+00:00"},
        {"event": "settled", "axis": "outer", "unit": "outer/10dps", "rate_dps": 10.0,
         "t_s": 140.0, "utc": "2026-01-01T00:00:14+00:00"},
    ]
    p = progress_of(decode_all(ev))
    assert p.step is not None and p.step.number == 2 and p.steps_done == 1
    assert p.bench_left_s == pytest.approx(200 + 300 - 40)
    assert p.speed == pytest.approx(10.0)
    assert p.wall_left_s == pytest.approx(46.0)
    assert p.fraction == pytest.approx(1 - 460 / 600)
    assert not p.completed


def test_tail_skips_partial_and_torn_lines(tmp_path: Path) -> None:
    f = tmp_path / "x.jsonl"
    f.write_text("".join(json.dumps({"i": i}) + "\n" for i in range(100)) + '{"i": 10')
    recs = tail_records(f, 50, Counted)
    assert [r.i for r in recs] == list(range(100 - len(recs), 100)) and 0 < len(recs) < 10
    assert tail_records(tmp_path / "missing.jsonl", 50, Counted) == []


class Counted(msgspec.Struct):
    i: int


@pytest.mark.parametrize("units,scale", [("deg/s", 1.0), ("rad", 200 * 180 / math.pi)])
def test_fog_trace_decodes_the_capture_tail(tmp_path: Path, units: str, scale: float) -> None:
    fmt = get_format("kvh-a")
    n = 2000
    truth_dps = np.linspace(-5.0, 5.0, n)
    rates = np.zeros((n, 3))
    rates[:, 2] = truth_dps / scale
    raw = tmp_path / "outer-fog.bin"
    raw.write_bytes(fmt.encode(np.arange(n) % fmt.sequence_modulus, rates).tobytes())
    tr = fog_trace(raw, FogSettings(port="/dev/null", rate_hz=200.0, units=units),
                   tail_s=5.0)  # last 1000
    assert len(tr.t_s) == len(tr.rate_dps) > 0
    assert tr.t_s[0] == pytest.approx(1000 / 200 + (math.ceil(1000 / 600) - 1) / 2 / 200)
    k = math.ceil(1000 / 600)
    want = truth_dps[1000:1000 + 1000 // k * k].reshape(-1, k).mean(axis=1)
    assert np.allclose(tr.rate_dps, want, rtol=1e-6, atol=1e-5)   # float32 frames


# -- security: token, Host header, traversal -------------------------------------------

def hand_made_runs(tmp: Path) -> Path:
    """A runs folder with one hand-made run (a session start, a verdict, a stand): what
    the server's rules need, no bench run (tests/test_station_signing.py uses it too)."""
    run = tmp / "runs" / "20260101-000000-demo"
    run.mkdir(parents=True)
    (run / "events.jsonl").write_text(json.dumps(
        {"utc": "2026-01-01T00:00:00+00:00", "t_s": 0.0, "session": 1,
         "event": "session_start", "pid": 1}) + "\n")
    (run / "result.json").write_text('{"verdict": "pass"}')
    (run / "stand.yaml").write_text("stand: {maker: m, model: x, serial: S1}\n")
    return tmp / "runs"


@pytest.fixture(scope="module")
def runs_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    tmp_path = tmp_path_factory.mktemp("station")
    (tmp_path / "secret.txt").write_text("not for the web")
    return hand_made_runs(tmp_path)


def _client(runs: Path, host: str = "127.0.0.1"):
    app = create_app(StationSettings(runs, TOKEN, host, 8765),
                     send_signal=lambda pid, sig: pytest.fail("no signal may be sent"))
    return app.test_client()


#: a station configured for a non-loopback interface: an RFC 5737 documentation address,
#: never reached (the WSGI test client and the settings parser open no socket)
LAN_HOST = "192.0.2.1"


def test_remote_address_needs_the_token(runs_folder: Path) -> None:
    c = _client(runs_folder, host=LAN_HOST)
    remote = {"REMOTE_ADDR": "192.0.2.7"}
    host = {"Host": f"{LAN_HOST}:8765"}
    assert c.get("/", environ_base=remote, headers=host).status_code == 403
    ok = c.get("/", environ_base=remote, headers={**host, "X-Bench-Token": TOKEN})
    assert ok.status_code == 200
    local = c.get("/", environ_base={"REMOTE_ADDR": "127.0.0.1"}, headers=host)
    assert local.status_code == 200


def test_stop_needs_the_token_even_locally(runs_folder: Path) -> None:
    c = _client(runs_folder)
    r = c.post("/api/runs/20260101-000000-demo/stop")
    assert r.status_code == 403 and "token" in r.get_json()["error"]
    # with the token, a run whose process is gone is refused, and nothing is signalled
    r = c.post("/api/runs/20260101-000000-demo/stop", headers={"X-Bench-Token": TOKEN})
    assert r.status_code == 409


def test_foreign_host_header_is_refused(runs_folder: Path) -> None:
    assert _client(runs_folder).get("/", headers={"Host": "evil.example"}).status_code == 403


def test_serve_refuses_a_public_address_without_a_token(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("BENCH_STATION_TOKEN", raising=False)
    args = argparse.Namespace(runs="runs", records=None, port=0, host=LAN_HOST, token=None)
    with pytest.raises(SystemExit, match="token"):
        settings_from_args(args)
    s, made = settings_from_args(argparse.Namespace(**{**vars(args), "host": "127.0.0.1"}))
    assert made and len(s.token) >= 16


@pytest.fixture(scope="module")
def server(runs_folder: Path) -> Iterator[int]:
    """The station's server on the runs folder (in this process: `served_here`): its port."""
    with served_here("--runs", str(runs_folder), "--token", TOKEN) as port:
        yield port


@contextlib.contextmanager
def served_here(*args: str) -> Iterator[int]:
    """`bench serve ARGS` (on a free port) in a thread of this process: its settings from
    its own parser and settings_from_args, its app, and a waitress server made as
    bench/app/station/serve.py's `cmd_serve` makes it; yields the port. For the tests whose
    subject is the page, not the server's process: a `bench serve` process costs ~1.9 s
    of CPU in start-up and imports. The live page's test restarts a server process."""
    from waitress import create_server

    from bench.app.cli import build_parser
    from bench.app.station.serve import THREADS, settings_from_args

    settings, _ = settings_from_args(build_parser().parse_args(["serve", *args,
                                                                 "--port", "0"]))
    server = create_server(create_app(settings), host=settings.host, port=0,
                           threads=THREADS, ident="ratebench-station",
                           clear_untrusted_proxy_headers=False)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    try:
        yield int(server.effective_port)
    finally:
        server.close()
        thread.join(timeout=10)


def _start_server(runs: Path, port: int = 0) -> tuple[subprocess.Popen[str], int]:
    proc = subprocess.Popen([sys.executable, "-m", "bench", "serve", "--runs", str(runs),
                             "--port", str(port), "--token", TOKEN], cwd=ROOT, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    assert proc.stdout is not None
    line = proc.stdout.readline()
    m = re.search(r"http://127\.0\.0\.1:(\d+)/", line)
    assert m, line
    return proc, int(m.group(1))


def _stop(proc: subprocess.Popen[str]) -> None:
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()


def _raw_get(port: int, path: str) -> int:
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    conn.putrequest("GET", path, skip_host=True)
    conn.putheader("Host", f"127.0.0.1:{port}")
    conn.endheaders()
    status = conn.getresponse().status
    conn.close()
    return status


@pytest.mark.parametrize("path", [
    "/files/20260101-000000-demo/../../secret.txt",
    "/files/..%2F..%2Fsecret.txt/result.json",
    "/files/20260101-000000-demo/..%2F..%2Fsecret.txt",
    "/files/20260101-000000-demo/stand.yaml",          # in the run, but not a download
    "/files/%2e%2e/secret.txt",
    "/run/..",
    "/static/../../../../etc/passwd",
])
def test_path_traversal_is_refused(server: int, path: str) -> None:
    port = server
    assert _raw_get(port, path) in (400, 403, 404)
    assert _raw_get(port, "/files/20260101-000000-demo/result.json") == 200


# -- the page, in a real browser, during a simulated run --------------------------------

def _chromium() -> tuple[str, str] | None:
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver") or (
        "/usr/bin/chromedriver" if Path("/usr/bin/chromedriver").exists() else None)
    return (browser, driver) if browser and driver else None


#: chromium kept off the network (issue 40; the test guard sees only Python's sockets):
#: none of its own background traffic (component and safe-browsing updates, sync, field
#: trials, QUIC probes), every host name but the loopback ones unresolvable, and an
#: address literal sent to a dead proxy on loopback (loopback itself is always direct)
CHROMIUM_OFFLINE = (
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--no-first-run", "--no-default-browser-check", "--disable-default-apps",
    "--disable-extensions", "--disable-quic", "--disable-domain-reliability",
    "--metrics-recording-only",
    "--host-resolver-rules=MAP * ~NOTFOUND , EXCLUDE localhost, EXCLUDE 127.0.0.1",
    "--proxy-server=http://127.0.0.1:9",
)


def _browser(found: tuple[str, str], height: int, extra: tuple[str, ...] = ()):  # noqa: ANN202
    """Headless chromium through Debian's chromedriver, offline but for 127.0.0.1
    (`extra`: more of chromium's switches)."""
    from selenium import webdriver
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service

    opts = Options()
    opts.binary_location = found[0]
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
              f"--window-size=1280,{height}", *CHROMIUM_OFFLINE, *extra):
        opts.add_argument(a)
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    return webdriver.Chrome(service=Service(found[1]), options=opts)


def _slow_demo(tmp: Path) -> Path:
    """One axis, one rate pair, clock at 5x (about 25 s of wall time): slow enough for a person (and the test) to
    watch the steps advance, short enough for CI."""
    stand = yaml.safe_load((CONFIGS / "stands" / "sim-two-axis.yaml").read_text())
    stand["sim"]["clock_speed"] = 5
    (tmp / "stand.yaml").write_text(yaml.safe_dump(stand, sort_keys=False))
    proc = yaml.safe_load((CONFIGS / "procedures" / "demo.yaml").read_text())
    proc.update(stand="stand.yaml", turns=2, static_record_s=10,
                axes={"outer": {"rates_dps": [30]}})
    (tmp / "station-demo.yaml").write_text(yaml.safe_dump(proc, sort_keys=False))
    return tmp / "station-demo.yaml"


def assert_printed(words: list[str], value: float, u: float) -> None:
    """`words` are "value ± U" as the page prints them (the certificate's rule: U to two
    significant digits, the value to the same decimal); they must be `value` and `u`
    rounded to that decimal (U may be rounded up: EA-4/02)."""
    v_text, pm, u_text = words[:3]
    assert pm == "±", words
    decimals = len(v_text.split(".")[1]) if "." in v_text else 0
    assert (len(u_text.split(".")[1]) if "." in u_text else 0) == decimals, words
    step = 10.0 ** -decimals
    printed = float(v_text.replace("\u2212", "-"))
    assert abs(printed - value) <= step / 2 * (1 + 1e-9), (words, value)
    assert -step / 2 <= float(u_text) - u <= step * (1 + 1e-9), (words, u)


def assert_finished_page(driver, how: str) -> None:  # noqa: ANN001
    """A finished run's page shows its end: the bar full for a completed plan (or where
    it stopped), the step line saying how it ended, and the instruments' last state as
    wall times, not a live "last update N s ago" that only grows."""
    from selenium.webdriver.common.by import By

    bar = driver.find_element(By.ID, "progress")
    step = driver.find_element(By.ID, "step").text
    if how in ("passed", "failed"):
        assert float(bar.get_attribute("value")) == 1.0, bar.get_attribute("value")
        assert step.startswith("Completed: all ") and step.endswith(f"the run {how}"), step
    else:
        assert step.lower().startswith(how), step
    assert driver.find_element(By.ID, "status").text == how
    health = driver.find_element(By.ID, "health").text
    assert "Instruments at the end of the run" in health, health
    assert " s ago" not in driver.find_element(By.TAG_NAME, "main").text
    assert "STALE" not in health


def _wait(cond, timeout_s: float, what: str, poll_s: float = 0.2):  # noqa: ANN001, ANN202
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = cond()
        if value:
            return value
        time.sleep(poll_s)
    pytest.fail(f"timed out after {timeout_s} s waiting for {what}")


@pytest.mark.timeout(400)
def test_live_page_in_a_real_browser(tmp_path: Path) -> None:
    found = _chromium()
    if found is None:
        unavailable("chromium and chromium-driver are not installed (Debian packages "
                    "`chromium chromium-driver`; .ci/run installs them)")
    from selenium.webdriver.common.by import By

    runs = tmp_path / "runs"
    runs.mkdir()
    procedure = _slow_demo(tmp_path)
    run_proc = bench_bg("run", str(procedure), "--yes", "--out", str(runs))
    server_proc, port = _start_server(runs)
    driver = _browser(found, height=1400)
    try:
        def made() -> Path | None:
            found = next(iter(p for p in runs.iterdir() if p.is_dir()), None)
            if found is None and run_proc.poll() is not None:   # say why, not a timeout
                pytest.fail(f"bench run exited {run_proc.returncode} before making its run "
                            f"directory: {run_proc.communicate()[1][-3000:]}")
            return found

        run_dir = _wait(made, 60, "the run directory")
        base = f"http://127.0.0.1:{port}"
        driver.get(f"{base}/run/{run_dir.name}")

        def state(js: str):  # noqa: ANN202
            return driver.execute_script(f"return {js}")

        first = _wait(lambda: state("window.station?.state?.progress?.step?.number"), 60,
                      "a step on the page")
        # and bench time to pass in it: a step that has just begun after a step of no
        # estimated time (the prompt) leaves the fraction at exactly 0 (CI saw it once)
        _wait(lambda: (state("window.station?.state?.progress?.step?.number") or 0) > first
              and (state("window.station?.state?.progress?.fraction") or 0) > 0,
              120, "the step to advance")
        # the live figures while the run is surely going on (a step just advanced; on a
        # loaded machine the 5x run may have ended by the time the plot fills, CI saw it)
        frac_mid = state("window.station?.state?.progress?.fraction")
        assert 0 < frac_mid < 1
        assert "Step" in driver.find_element(By.ID, "step").text
        assert "wall time left" in driver.find_element(By.ID, "eta").text
        # the view is not in the run's path: a server restart and a page reload lose
        # nothing; the page reconnects by itself and goes on showing the run
        _stop(server_proc)
        server_proc, _ = _start_server(runs, port)
        seen = state("window.station.updates")
        _wait(lambda: state("window.station.updates") > seen, 60,
              "the page to reconnect to the restarted server")
        assert run_proc.poll() is None, "the run must not notice the view going away"
        driver.refresh()
        second = _wait(lambda: state("window.station?.state?.progress?.step?.number"), 60,
                       "a step on the reloaded page")
        assert second >= first
        _wait(lambda: (driver.execute_script(
            "return window.station?.charts?.fog?.data[0].length") or 0) > 10, 90,
            "FOG points in the plot")
        frac = state("window.station?.state?.progress?.fraction")
        assert frac_mid <= frac <= 1
        driver.save_screenshot(str(ARTIFACTS / "live-run.png"))

        # the one action: a stop request with the token, exactly Ctrl-C
        driver.find_element(By.ID, "token").send_keys(TOKEN)
        driver.find_element(By.ID, "stop").click()
        _wait(lambda: "stop requested" in driver.find_element(By.ID, "stop-result").text, 20,
              "the stop request's answer")
        out, err = run_proc.communicate(timeout=120)
        assert run_proc.returncode == 3, err[-2000:]
        assert "interrupted by SIGINT" in err
        _wait(lambda: state("window.station?.state?.status") == "aborted", 30,
              "the page to show the abort")

        # the resume in this process (the console script's `main`): the stop above needed
        # a process of its own, the page watching the resumed run does not
        resumed = cli("run", "--resume", str(run_dir), "--yes")
        assert resumed.returncode == 0, resumed.stderr[-2000:]
        _wait(lambda: state("window.station?.state?.status") == "passed", 30,
              "the page to show the resumed run passed")
        assert state("window.station?.state?.sessions") == 2

        serial = yaml.safe_load((run_dir / "stand.yaml").read_text())["stand"]["serial"]
        driver.get(f"{base}/records/{serial}")
        _wait(lambda: driver.execute_script(
            "const i = document.getElementById('trend'); return i.complete && i.naturalWidth"),
            30, "the trend plot")
        assert run_dir.name in driver.find_element(By.ID, "history").text
        driver.save_screenshot(str(ARTIFACTS / "table-history.png"))
        print(f"screenshots: {ARTIFACTS / 'live-run.png'}, {ARTIFACTS / 'table-history.png'}")
    finally:
        driver.quit()
        if run_proc.poll() is None:
            run_proc.send_signal(signal.SIGINT)
            run_proc.wait(timeout=60)
        _stop(server_proc)


# -- health and results (issue 26) ------------------------------------------------------

def test_health_flags_a_silent_fog_only_while_running(tmp_path: Path) -> None:
    """Ages from the files' modification times, against a given `now` (hand-set mtimes)."""
    from bench.app.station.live import FOG_SILENT_S, STALE_S, health
    raw = tmp_path / "raw" / "s1"
    raw.mkdir(parents=True)
    (tmp_path / "events.jsonl").write_text("")
    for name in ("outer-fog.bin", "outer-drive.jsonl", "outer-counter.jsonl"):
        (raw / name).write_bytes(b"x")
    now = 1_000_000.0
    os.utime(tmp_path / "events.jsonl", (now - 1, now - 1))
    os.utime(raw / "outer-drive.jsonl", (now - 0.5, now - 0.5))
    os.utime(raw / "outer-counter.jsonl", (now - 0.5, now - 0.5))
    os.utime(raw / "outer-fog.bin", (now - FOG_SILENT_S - 1, now - FOG_SILENT_S - 1))
    tail = FogTrace(tail_s=30.0, tail_crc_errors=2, tail_lost_frames=0)
    acq = [_half(axis="outer", fog_lost=3), _half(axis="outer", fog_lost=1)]
    h = health(tmp_path, raw, ["outer"], True, tail, "outer", acq, now=now)
    assert h.axes[0].fog_lost_in_halves == 4 and h.axes[0].fog_tail_crc_errors == 2
    assert h.axes[0].fog_age_s == pytest.approx(FOG_SILENT_S + 1)
    assert h.last_update_s == pytest.approx(0.5) and not h.stale
    assert any(w.startswith("FOG outer: no data for 3 s") for w in h.warnings), h
    assert any("2 CRC errors" in w for w in h.warnings), h
    late = now + STALE_S + 1
    h = health(tmp_path, raw, ["outer"], True, tail, "outer", acq, now=late)
    assert h.stale and h.warnings[0].startswith("no update for")
    assert health(tmp_path, raw, ["outer"], False, tail, "outer", acq, now=late).warnings == []


@pytest.mark.timeout(400)
def test_page_warns_of_a_silent_fog_and_shows_the_final_results(tmp_path: Path) -> None:
    """A FOG twin that stops sending (its frames held for 40 bench seconds, while the rest
    of the bench runs on) shows a health warning on the page within 5 s; the finished run
    shows the final results table and no stop form."""

    from selenium.webdriver.common.by import By

    from bench.app.commands import run_session
    from bench.core.journal import RunDir
    from bench.core.loader import load_config
    from sims.fog_twin import Stall
    from tests.conftest import when_step_starts

    found = _chromium()
    assert found, "chromium and chromium-driver are needed (.ci/run installs them)"
    runs = tmp_path / "runs"
    runs.mkdir()
    cfg = load_config(_slow_demo(tmp_path))
    run = RunDir.create(runs, cfg.procedure_path, cfg.stand_path)
    silenced: dict[str, float] = {}

    def silence(sim) -> None:  # noqa: ANN001
        fog = sim.twins["outer.fog"]
        fog.inject(Stall(fog.next_sample + 50, duration_s=40.0, lose=False))
        silenced["t"] = time.monotonic()

    def hook(sim) -> None:  # noqa: ANN001
        when_step_starts(run, lambda e: e.get("action") == "acquire", lambda: silence(sim),
                         delay_s=0.5)

    outcome: dict[str, int] = {}
    bench = threading.Thread(target=lambda: outcome.setdefault(
        "status", run_session(cfg, run, yes=True, on_sim_started=hook)), daemon=True)
    server_proc, port = _start_server(runs)
    driver = _browser(found, height=1600)
    try:
        bench.start()
        _wait(lambda: (run.path / "events.jsonl").exists(), 60, "the run's journal")
        driver.get(f"http://127.0.0.1:{port}/run/{run.path.name}")
        _wait(lambda: driver.find_elements(By.ID, "stop"), 30, "the stop form while running")
        _wait(lambda: "t" in silenced, 120, "the FOG twin to be silenced")

        def warned() -> bool:
            text = driver.find_element(By.ID, "health-warnings").text
            return "FOG outer: no data" in text

        _wait(warned, 5.0, "a health warning within 5 s of the FOG falling silent",
              poll_s=0.1)
        print(f"health warning after {time.monotonic() - silenced['t']:.1f} s")
        driver.save_screenshot(str(ARTIFACTS / "fog-silent.png"))
        bench.join(timeout=300)
        assert outcome.get("status") == 0, outcome
        _wait(lambda: driver.execute_script("return window.station?.state?.status")
              == "passed", 30, "the page to show the run passed")
        _wait(lambda: len(driver.find_elements(
            By.CSS_SELECTOR, "#rates-outer.final tbody tr")) == 2, 30,
            "the final results table (+30 and -30 deg/s)")
        result = json.loads((run.path / "result.json").read_text())
        rate = result["axes"]["outer"]["rates"][0]
        row = driver.find_element(By.CSS_SELECTOR, "#rates-outer tbody tr").text
        assert_printed(row.split()[2:5], rate["rate_error_rel"] * 1e6,
                       rate["rate_error_U_rel"] * 1e6)         # "δ ± U" in ppm
        assert "PASS" in row
        assert not driver.find_elements(By.ID, "stop")      # the live page dropped it
        assert_finished_page(driver, "passed")              # the live page, ended
        driver.refresh()
        _wait(lambda: driver.execute_script("return window.station?.state?.status")
              == "passed", 30, "the reloaded page")
        assert not driver.find_elements(By.ID, "stop")      # and a fresh page has none
        assert driver.find_elements(By.CSS_SELECTOR, "#rates-outer.final tbody tr")
        assert_finished_page(driver, "passed")
        log = driver.find_element(By.ID, "log").text
        assert "settled: outer at +30 deg/s" in log, log
        driver.save_screenshot(str(ARTIFACTS / "finished-run.png"))
    finally:
        driver.quit()
        bench.join(timeout=120)
        _stop(server_proc)


def test_results_rows_as_they_come_and_final() -> None:
    from bench.app.station.live import final_rows, pair_rows
    from bench.report.result_frame import ResultFrame
    events = [{"event": "settled", "axis": "outer", "unit": "outer/10dps", "rate_dps": 10.0},
              {"event": "pair", "axis": "outer", "unit": "outer/10dps", "k": 1.0003,
               "k_u": 4e-6, "w0_dps": 0.002, "w0_u_dps": 4e-5,
               "directions": [{"set_rate_dps": 10.0, "turns": 4, "rate_error_rel": -1e-7,
                               "rate_error_U_rel": 6e-8, "rate_instability_rel": 3e-8,
                               "verdict": "pass"},
                              {"set_rate_dps": -10.0, "turns": 4, "rate_error_rel": 2e-5,
                               "rate_error_U_rel": 1e-7, "rate_instability_rel": 5e-8,
                               "verdict": "fail"}]}]
    from procedures.rate_ladder.events import ResultRow
    rows = pair_rows(decode_all(events))
    assert all(isinstance(r, ResultRow) for r in rows)
    assert [(r.set_rate_dps, r.verdict, r.k) for r in rows if isinstance(r, ResultRow)] == [
        (10.0, "pass", 1.0003), (-10.0, "fail", 1.0003)]
    result = {"axes": {"outer": {
        "rates": [{"set_rate_dps": 10.0, "rate_error_rel": -1e-7, "rate_error_u_rel": 6e-8,
                   "rate_instability_rel": 3e-8, "turns": 4, "verdict": "pass"}],
        "pairs": [{"rate_dps": 10.0, "k": 1.0003, "k_u": 4e-6, "w0_dps": 0.002,
                   "w0_u_dps": 4e-5}]}}}
    (row,) = final_rows(ResultFrame.of(result))
    assert isinstance(row, ResultRow)
    assert row.k == 1.0003 and row.rate_error_U_rel == 6e-8 and row.verdict == "pass"
    assert final_rows(ResultFrame.of({"axes": {"outer": "damaged"}})) == []
