"""JSON is read and passed around only in codec modules (issue 60).

Each kind's result is one typed model, decoded from result.json in its codec module
(procedures/<kind>/codec.py, bench/core/events.py for the journal) and read by attributes
everywhere else. tests/json_boundary.py counts, per file and by walking the code, the JSON
reads (`json.load(s)` and the project's own JSON readers) and the signatures that take or
return a JSON map (`Mapping[str, object]`, `dict[str, object]`, `JsonObject`, or an alias
of one). Today's offenders are listed in tests/json_boundary_allowed.py, generated once: a
file not listed must have none, and a listed file may not gain any (lower its numbers when
you convert it; never raise them).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.json_boundary import CODECS, ROOT, SCANNED, count, offences
from tests.json_boundary_allowed import ALLOWED

PLANTED_MODULE = '''\
"""A module that reads result.json itself and passes the map on."""
import json
from collections.abc import Mapping
from pathlib import Path

Doc = dict[str, object]


def verdict(result: Mapping[str, object]) -> str:
    return str(result["verdict"])


def load(path: Path) -> Doc:
    data = json.loads(path.read_text())
    return data if isinstance(data, dict) else {}


def verdict_of(path: Path) -> str:
    return verdict(load(path))
'''


@pytest.fixture(scope="module")
def found() -> dict[str, dict[str, int]]:
    return count()


def test_json_stays_in_the_codecs(found: dict[str, dict[str, int]]) -> None:
    assert offences(found, ALLOWED) == []


def test_the_drift_kinds_result_readers_are_off_the_list(found: dict[str, dict[str, int]]
                                                         ) -> None:
    """The drift kind's model, analysis and readers hold no JSON map (issue 60's slice);
    what is left in its files is the kind interface's (bench/kind's Protocols pass the
    result document), the raw DMM journal and corrections.json."""
    drift = {p for p in found if p.startswith("procedures/drift_pulse/")}
    for module in ("result", "analysis", "certificate", "dcc", "budgets", "plots"):
        assert f"procedures/drift_pulse/{module}.py" not in drift
        assert f"procedures/drift_pulse/{module}.py" not in ALLOWED
    assert "procedures/drift_pulse/codec.py" in CODECS


def _tree_copy(tmp_path: Path) -> Path:
    """A copy of the scanned layers under tmp_path (the planted code never enters the tree
    itself)."""
    for d in SCANNED:
        shutil.copytree(ROOT / d, tmp_path / d, ignore=shutil.ignore_patterns("__pycache__"))
    return tmp_path


@pytest.mark.parametrize("where", ["bench/report/dcc", "bench/app/station"])
def test_a_planted_module_fails(tmp_path: Path, where: str) -> None:
    """A new module reading JSON and taking a JSON map, in the DCC or the station: its
    json.loads, its call of its own reader `load` (a JSON map through the alias `Doc`), and
    its two map signatures are found, though none is named as the guard expects."""
    root = _tree_copy(tmp_path)
    (root / where / "planted.py").write_text(PLANTED_MODULE, encoding="utf-8")
    found = count(root, (where,))
    assert found[f"{where}/planted.py"] == {"json_map_signatures": 2, "json_reads": 2}
    allowed = {p: c for p, c in ALLOWED.items() if p.startswith(where)}
    assert offences(found, allowed) == [
        f"{where}/planted.py: json_map_signatures 2 > 0 allowed",
        f"{where}/planted.py: json_reads 2 > 0 allowed"]


def test_a_listed_file_that_grows_fails(tmp_path: Path) -> None:
    """A file on the list gains one more map signature: it is named with its new count.
    (The station's files are off the real list since issue 60's station slice, so the
    list here is made up: live.py allowed one, given two.)"""
    where = "bench/app/station"
    listed = f"{where}/live.py"
    allowed = {**ALLOWED, listed: {"json_map_signatures": 1}}
    root = _tree_copy(tmp_path)
    with (root / listed).open("a", encoding="utf-8") as f:
        for name in ("planted", "planted_too"):
            f.write(f"\n\ndef {name}(doc: dict[str, object]) -> int:\n    return len(doc)\n")
    found = count(root, (where,))
    assert offences(found, allowed) == [f"{listed}: json_map_signatures 2 > 1 allowed"]


def test_a_codec_may_read_json(tmp_path: Path) -> None:
    """The same module as a codec is not counted."""
    where = "procedures/drift_pulse"
    root = _tree_copy(tmp_path)
    (root / where / "codec.py").write_text(PLANTED_MODULE, encoding="utf-8")
    assert f"{where}/codec.py" not in count(root, (where,))


ANY_READER = '''\
"""A reader typed `Any` in one module, its caller in another."""
import json
from pathlib import Path
from typing import Any


def read_any(path: Path) -> dict[str, Any]:
    data = json.loads(path.read_text())
    return data if isinstance(data, dict) else {}
'''


def test_a_reader_typed_any_is_still_a_reader(tmp_path: Path) -> None:
    """A JSON reader whose return is `dict[str, Any]` (the form the guard once missed:
    records/extract.py read result.json and meta.json through one) is a reader: its
    callers outside the codecs are counted, though its signature is not a JSON map's."""
    root = _tree_copy(tmp_path)
    (root / "bench/report/certificate/anyread.py").write_text(ANY_READER, encoding="utf-8")
    (root / "bench/app/station/uses.py").write_text(
        "from pathlib import Path\n"
        "from bench.report.certificate.anyread import read_any\n\n\n"
        "def verdict(p: Path) -> str:\n"
        "    return str(read_any(p).get('verdict'))\n", encoding="utf-8")
    found = count(root, ("bench/app/station", "bench/report/certificate"))
    assert found["bench/app/station/uses.py"] == {"json_reads": 1}
    assert found["bench/report/certificate/anyread.py"] == {"json_reads": 1}
