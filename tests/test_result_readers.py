"""result.json is read through the kinds' typed results, not key by key (issue 45).

A *result reader* is, in a module that reads results (the certificate, the DCC, the
records, the station, the summary, and the kinds' modules that feed them):
- a `.to_dict(` call (a typed value turned back into an untyped one);
- a subscript with a string constant, or a `.get("...")` call, on a value named as a result
  or a part of one (RESULT_NAMES: `result`, `r`, `rate`, `pair`, `ax`...) or on an
  attribute `.result` (`src.result["axes"]`);
- an annotation `dict[str, Any]` / `Mapping[str, Any]` of a parameter so named.
The kinds' result modules (procedures/<kind>/result.py, bench/report/result_frame.py) are
where the keys are spelled, and are not scanned. ALLOWED counts what is left to convert:
a file may only go down (lower its number when you convert readers; never raise it).
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

READER_DIRS = ("bench/app/certificate", "bench/app/dcc", "bench/app/records",
               "bench/app/station", "bench/report/certificate")
READER_FILES = ("bench/app/summary.py",)
KIND_READERS = ("certificate.py", "dcc.py", "records.py", "budgets.py", "conditions.py")

#: names that hold a result.json or a part of one
RESULT_NAMES = frozenset({"result", "results", "res", "r", "rate", "rates", "pair", "pairs",
                          "p", "ax", "axis_result", "entry", "floor", "noise_floor",
                          "systematic", "sysc", "mains", "h", "harmonic", "intra",
                          "intra_turn", "check", "c"})

#: file -> result readers left (may only shrink)
ALLOWED: dict[str, int] = {}


def reader_files() -> list[Path]:
    files = [p for d in READER_DIRS for p in sorted((ROOT / d).rglob("*.py"))]
    files += [ROOT / f for f in READER_FILES]
    for kind in sorted((ROOT / "procedures").iterdir()):
        files += [kind / f for f in KIND_READERS if (kind / f).exists()]
    return files


def _named_result(node: ast.expr) -> bool:
    if isinstance(node, ast.Name):
        return node.id in RESULT_NAMES
    if isinstance(node, ast.Attribute):
        return node.attr == "result" or node.attr in RESULT_NAMES
    return False


def _any_mapping(ann: ast.expr | None) -> bool:
    """`dict[str, Any]`, `Mapping[str, Any]` (or typing's spelling of them)."""
    if not isinstance(ann, ast.Subscript) or not isinstance(ann.slice, ast.Tuple):
        return False
    base = ann.value
    name = base.id if isinstance(base, ast.Name) else (
        base.attr if isinstance(base, ast.Attribute) else "")
    args = ann.slice.elts
    return (name in ("dict", "Dict", "Mapping", "MutableMapping") and len(args) == 2
            and isinstance(args[1], ast.Name) and args[1].id == "Any")


def result_readers(source: str, filename: str = "<source>") -> list[str]:
    """Every result reader in `source`, as `line: what`."""
    found: list[str] = []
    for node in ast.walk(ast.parse(source, filename)):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            if node.func.attr == "to_dict":
                found.append(f"{node.lineno}: .to_dict()")
            elif (node.func.attr == "get" and _named_result(node.func.value) and node.args
                  and isinstance(node.args[0], ast.Constant)
                  and isinstance(node.args[0].value, str)):
                found.append(f"{node.lineno}: .get({node.args[0].value!r})")
        elif (isinstance(node, ast.Subscript) and _named_result(node.value)
              and isinstance(node.slice, ast.Constant) and isinstance(node.slice.value, str)):
            found.append(f"{node.lineno}: [{node.slice.value!r}]")
        elif isinstance(node, ast.arg) and node.arg in RESULT_NAMES and _any_mapping(
                node.annotation):
            found.append(f"{node.lineno}: {node.arg}: untyped mapping")
    return found


def count_readers() -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for path in reader_files():
        hits = result_readers(path.read_text(encoding="utf-8"), str(path))
        if hits:
            out[str(path.relative_to(ROOT))] = hits
    return out


def test_result_readers_only_shrink() -> None:
    grown = []
    for name, hits in count_readers().items():
        allowed = ALLOWED.get(name, 0)
        if len(hits) > allowed:
            grown.append(f"{name}: {len(hits)} result readers, {allowed} allowed: "
                         + "; ".join(hits[:8]))
    assert not grown, ("read result.json through the kind's typed result "
                       "(procedures/<kind>/result.py):\n" + "\n".join(grown))


def test_a_planted_reader_is_caught() -> None:
    planted = (
        "from typing import Any\n"
        "def rows(src, result: dict[str, Any], pa):\n"
        "    for r in result['axes']['outer']['rates']:\n"
        "        yield r.get('rate_error_rel'), src.result['verdict'], pa.pair.to_dict()\n")
    hits = result_readers(planted)
    assert hits == ["2: result: untyped mapping", "3: ['axes']",
                    "4: .get('rate_error_rel')", "4: .to_dict()", "4: ['verdict']"] or \
        sorted(hits) == sorted(["2: result: untyped mapping", "3: ['axes']",
                                "4: .get('rate_error_rel')", "4: .to_dict()",
                                "4: ['verdict']"]), hits
    # typed reads are not readers
    assert result_readers("def f(result):\n    return result.frame.verdict, result.axes\n") \
        == []


def test_the_result_modules_are_not_scanned() -> None:
    names = {str(p.relative_to(ROOT)) for p in reader_files()}
    assert "procedures/rate_ladder/result.py" not in names
    assert "bench/report/result_frame.py" not in names
    assert "procedures/rate_ladder/certificate.py" in names


def test_the_ladder_result_round_trips_and_refuses_by_key_path() -> None:
    import json

    import pytest

    from bench.report.codec import encode
    from bench.report.codec import written as encoded
    from procedures.rate_ladder.codec import conform, ladder_of
    from procedures.rate_ladder.result import LadderBody, MalformedResult, Systematic
    from procedures.rate_ladder.sample import rate_ladder_result

    doc = encode(rate_ladder_result())
    typed = ladder_of(doc)
    outer = typed.axes["outer"]
    assert outer.rates[0].set_rate_dps == doc["axes"]["outer"]["rates"][0]["set_rate_dps"]
    assert outer.pairs[0].k == doc["axes"]["outer"]["pairs"][0]["k"]
    # the model's encoding is what it decodes from, key for key (result.json's bytes)
    written = json.dumps(encoded(LadderBody(axes=typed.axes)))
    again = ladder_of({**doc, **json.loads(written)})
    assert json.dumps(encoded(LadderBody(axes=again.axes))) == written
    bad = json.loads(json.dumps(doc))
    bad["axes"]["outer"]["rates"][0]["systematic"] = "garbage"
    with pytest.raises(MalformedResult, match=r"axes\.outer\.rates\[0\]\.systematic "
                                              "expected a mapping, found str"):
        ladder_of(bad)
    lenient, dropped = conform(bad)
    assert dropped == ["axes.outer.rates[0].systematic (expected a mapping, found str)"]
    assert lenient.axes["outer"].rates[0].systematic == Systematic()
    # a leaf of the wrong type: refused by msgspec, named in result.json's terms; the
    # certificate's lenient reading drops it (the rest of the entry kept)
    bad = json.loads(json.dumps(doc))
    bad["axes"]["outer"]["rates"][1]["turns"] = "four"
    with pytest.raises(MalformedResult, match=r"axes\.outer\.rates\[1\]\.turns expected an "
                                              "integer or null, got str"):
        ladder_of(bad)
    lenient, dropped = conform(bad)
    assert dropped == ["axes.outer.rates[1].turns (expected an integer or null, got str)"]
    assert lenient.axes["outer"].rates[1].turns is None
    assert lenient.axes["outer"].rates[1].rate_error_rel == outer.rates[1].rate_error_rel


# -- the writer side: the analysis computes, the kind's result module spells ----------------

def json_writers(source: str, filename: str = "<source>") -> list[str]:
    """Every `to_dict`/`to_json` method in `source`, as `line: name`."""
    return [f"{n.lineno}: {n.name}" for n in ast.walk(ast.parse(source, filename))
            if isinstance(n, ast.FunctionDef) and n.name in ("to_dict", "to_json")]


def test_the_analysis_spells_no_result_key() -> None:
    """bench/analysis returns typed values; the ladder's result module lays them out as
    result.json (procedures/rate_ladder/result.py `rate_entry`, `pair_entry`), so a key is
    spelled where it is read back, once."""
    found = [f"{p.relative_to(ROOT)}:{w}" for p in sorted((ROOT / "bench/analysis").rglob("*.py"))
             for w in json_writers(p.read_text(encoding="utf-8"), str(p))]
    assert found == [], found


def test_a_planted_writer_in_the_analysis_is_found() -> None:
    planted = ("from dataclasses import dataclass\n@dataclass\nclass R:\n    x: float\n"
               "    def to_dict(self):\n        return {'x_rel': self.x}\n")
    assert json_writers(planted) == ["5: to_dict"]
