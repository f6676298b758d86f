"""A run folder's corrections file (issue 58) broken the ways a person or a disk breaks it:
`bench analyze` refuses it with exit 2, naming the file and the key, never a traceback,
and leaves the result it had untouched."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import DemoRun, bench

BROKEN = {
    "torn": ('{"corrections": [{"where": 5', "not JSON"),
    "value text": ('{"corrections": [{"where": "axes.outer.counter", "quantity": '
                   '"timebase_offset_rel", "value": "x"}]}', "corrections[0].value"),
    "U negative": ('{"corrections": [{"where": "axes.outer.counter", "quantity": '
                   '"timebase_offset_rel", "value": 1e-7, "U": -1}]}', "corrections[0].U"),
}


@pytest.mark.parametrize("name", sorted(BROKEN))
def test_a_broken_corrections_file_is_refused_by_name(demo_run: DemoRun, tmp_path: Path,
                                                      name: str) -> None:
    text, key = BROKEN[name]
    run = demo_run.copy_to(tmp_path / "runs")
    before = (run / "result.json").read_bytes()
    (run / "corrections.json").write_text(text)
    done = bench("analyze", str(run))
    assert done.returncode == 2, done.stdout + done.stderr
    assert "Traceback" not in done.stderr
    assert f"bench analyze: not analysed: {run / 'corrections.json'}: " in done.stderr
    assert key in done.stderr, done.stderr
    assert (run / "result.json").read_bytes() == before
