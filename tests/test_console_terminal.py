"""The operator's console on a real terminal: the demo under a pseudo-terminal.

A person's view: `bench run` without --yes on a pty (python's pty module: the process
sees a terminal on stdin, stdout and stderr), answering each set-up prompt with Enter as
it appears. Checked: the live display advances step by step and never says "0 s" of wall
time left before the last step; the prompts reach the journal and the certificate as
answered by the operator; every figure of the summary is the certificate's text for the
same quantity (read back from certificate.html); the version is in the run directory.
"""

from __future__ import annotations

import fcntl
import json
import os
import re
import select
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path

import lxml.html
import pytest

import bench
from tests.conftest import CONFIGS, ROOT

DEMO = CONFIGS / "procedures" / "demo.yaml"
ANSI = re.compile(r"\x1b\[[0-9;?]*[ -/]*[@-~]|\x1b[()][0-9A-Za-z]|\x1b[=>]")
FRAME = re.compile(r"step (\d+)/(\d+)\s+(\d+) %\s+bench time left (.+?)\s+"
                   r"(time to go not yet measured|about (< 0\.1 s|[\d.]+ s|\d+ min \d+ s) "
                   r"to go)")
# The certificate's header for a summary column whose console header differs
CERT_HEADER = {"Intra-turn raw ± U": "Raw ± U"}


def run_on_a_terminal(out_dir: Path, timeout_s: float = 280) -> tuple[int, str, int]:
    """`bench run DEMO` on a pty; Enter for each prompt. Returns (rc, output, answered)."""
    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 60, 220, 0, 0))
    env = {**os.environ, "TERM": "xterm-256color", "COLUMNS": "220", "LINES": "60"}
    env.pop("NO_COLOR", None)
    proc = subprocess.Popen([sys.executable, "-m", "bench", "run", str(DEMO), "--out",
                             str(out_dir)], cwd=ROOT, stdin=slave, stdout=slave,
                            stderr=slave, env=env, close_fds=True)
    os.close(slave)
    buf, answered, seen = b"", 0, 0
    deadline = time.monotonic() + timeout_s
    try:
        while time.monotonic() < deadline:
            ready, _, _ = select.select([master], [], [], 0.2)
            if ready:
                try:
                    data = os.read(master, 1 << 16)
                except OSError:        # the child closed the terminal
                    break
                if not data:
                    break
                buf += data
                asked = buf.count(b"Press Enter when done")
                if asked > seen:       # a person reads the prompt, then presses Enter
                    seen = asked
                    os.write(master, b"\n")
                    answered += 1
            elif proc.poll() is not None:
                break
        rc = proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
        os.close(master)
    return rc, buf.decode("utf-8", "replace"), answered


def plain(text: str) -> str:
    return ANSI.sub("", text).replace("\r\n", "\n").replace("\r", "\n")


def certificate_tables(html: str) -> list[tuple[str, list[str], list[list[str]]]]:
    """(caption, header, rows) of every captioned table of certificate.html."""
    out = []
    for cap in lxml.html.fromstring(html).find_class("caption"):
        table = cap.getnext()
        if table is None or table.tag != "table":
            continue
        header = [th.text_content() for th in table.iter("th")]
        rows = [[td.text_content() for td in tr.iter("td")]
                for tr in table.iter("tr") if tr.find("td") is not None]
        out.append((cap.text_content(), header, rows))
    return out


def summary_tables(text: str) -> list[tuple[str, list[str], list[list[str]]]]:
    """(title, header, rows) of the printed summary: a title, a header, a rule, rows."""
    lines = text.splitlines()
    out = []
    for i, line in enumerate(lines[:-2]):
        if lines[i + 2].startswith("---") and set(lines[i + 2]) == {"-"}:
            header = re.split(r"\s{2,}", lines[i + 1].strip())
            rows = []
            for row in lines[i + 3:]:
                if not row.strip():
                    break
                rows.append(re.split(r"\s{2,}", row.strip()))
            out.append((line.strip(), header, rows))
    return out


@pytest.mark.timeout(320)
def test_demo_on_a_terminal_live_display_prompts_and_summary(tmp_path: Path) -> None:
    rc, raw, answered = run_on_a_terminal(tmp_path)
    text = plain(raw)
    assert rc == 0, text[-3000:]
    run_dir = Path(text.strip().splitlines()[-1].strip())
    assert run_dir.parent == tmp_path, text[-500:]

    # the live display: frames of the overall bar, in order, up to the last step
    frames = [m.groups() for m in FRAME.finditer(text)]
    steps = [int(f[0]) for f in frames]
    total = int(frames[0][1])
    assert total == 58 and steps == sorted(steps) and steps[-1] == total, steps
    assert len(set(steps)) >= 40, f"only {len(set(steps))} of {total} steps were shown"
    percents = [int(f[2]) for f in frames]
    assert percents == sorted(percents) and percents[0] < 10 and percents[-1] >= 95, percents
    walls = [(int(f[0]), f[5]) for f in frames if f[5] is not None]
    assert walls and walls[0][0] < 10, "no wall-time estimate early in the run"
    for step, wall in walls:
        if step < total:
            assert wall not in ("0 s", "0.0 s"), f"step {step}/{total}: wall time left {wall}"
    early = next(w for s, w in walls if s >= 5)
    assert not early.startswith(("< ", "0.")), f"at step 5 the estimate was {early}"
    # the per-step bar and the latest readings under it
    assert re.search(r"\d of [24] turns timed at [+-]\d+ deg/s", text)
    assert re.search(r"within ±[\d.]+ deg/s for [\d.]+ of 2 s", text)
    assert "latest per-turn rate deviation: " in text and "latest FOG mean: " in text

    # the prompts: asked on the terminal, answered by a person, journaled, certified
    events = [json.loads(line) for line in (run_dir / "events.jsonl").read_text().splitlines()]
    prompts = [e for e in events if e["event"] == "prompt"]
    assert answered == len(prompts) == 2
    assert all(e["answered_by"] == "operator" and e["answered_utc"] >= e["asked_utc"]
               for e in prompts)
    html = (run_dir / "certificate.html").read_text(encoding="utf-8")
    assert html.count("confirmed by the operator (Enter)") == 2
    assert "--yes" not in html

    # the version: in the run directory, the session and the certificate
    assert json.loads((run_dir / "meta.json").read_text())["bench_version"] == bench.__version__
    assert next(e for e in events if e["event"] == "session_start")["version"] == \
        bench.__version__
    assert f"run with ratebench {bench.__version__}" in html

    # every figure of the summary is the certificate's text for the same quantity
    cert = certificate_tables(html)
    summary = summary_tables(text[text.rindex("wrote "):])
    assert len(summary) == 4, [s[0] for s in summary]
    compared = 0
    for title, header, rows in summary:
        axis = title.split()[1].rstrip(",")
        for row in rows:
            assert len(row) == len(header), (title, header, row)
            for name, cell in zip(header[1:], row[1:], strict=True):
                want = CERT_HEADER.get(name.split(",")[0], None)
                cert_name = (want + name[len(name.split(",")[0]):]) if want else name
                matches = [r[h.index(cert_name)] for cap, h, rs in cert
                           if cap.startswith(f"Axis {axis}:") and cert_name in h
                           for r in rs if r[0] == row[0]]
                assert matches == [cell], (title, row[0], name, cell, matches)
                compared += 1
    assert compared >= 10 * 6 + 5 * 2, compared
    # the unresolved figures as the certificate prints them: an upper limit, "< x"
    assert any(cell.startswith("< ") for _, _, rows in summary for row in rows for cell in row)
    assert text.rstrip().splitlines()[-2].strip() == "verdict: PASS"
