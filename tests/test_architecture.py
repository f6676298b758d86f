"""The import contract (pyproject.toml, `lint-imports`): layers import downwards only, no
import cycles, and the contract really fails when a lower layer imports a higher one.

These run the real tool on the real source tree (and on a copy with one bad import
added), the way CI does.
"""

from __future__ import annotations

import ast
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import grimp

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("bench", "drivers", "procedures", "sims")


def import_cycles(packages: tuple[str, ...] = PACKAGES) -> list[list[str]]:
    """Every set of our modules that import each other in a circle (Tarjan's strongly
    connected components of the module import graph, function-level imports included)."""
    graph = grimp.build_graph(*packages, cache_dir=None)
    edges = {m: sorted(graph.find_modules_directly_imported_by(m)) for m in graph.modules}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in edges.get(v, []):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1 or v in edges.get(v, []):
                out.append(sorted(component))

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10_000))
    for module in sorted(graph.modules):
        if module not in index:
            visit(module)
    return out


def lint_imports(root: Path) -> subprocess.CompletedProcess[str]:
    exe = Path(sys.executable).parent / "lint-imports"
    env = {**os.environ, "PYTHONPATH": str(root)}
    return subprocess.run([str(exe), "--no-cache"], cwd=root, env=env, capture_output=True,
                          text=True, timeout=120)


def test_the_import_contract_is_kept() -> None:
    r = lint_imports(ROOT)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "0 broken" in r.stdout


def test_no_import_cycles() -> None:
    assert import_cycles() == []


def _copy_tree(dst: Path) -> None:
    for pkg in PACKAGES:
        shutil.copytree(ROOT / pkg, dst / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", dst / "pyproject.toml")


def test_the_contract_fails_when_a_driver_imports_the_engine(tmp_path: Path) -> None:
    _copy_tree(tmp_path)
    with open(tmp_path / "drivers" / "units.py", "a") as f:
        f.write("\nfrom bench.core.engine import Abort  # noqa: E402,F401 - the bad import\n")
    r = lint_imports(tmp_path)
    assert r.returncode != 0
    assert "Layers import downwards only BROKEN" in r.stdout
    assert "drivers.units -> bench.core.engine" in r.stdout


def test_the_contract_fails_when_a_twin_imports_the_analysis(tmp_path: Path) -> None:
    _copy_tree(tmp_path)
    with open(tmp_path / "sims" / "platform.py", "a") as f:
        f.write("\nfrom bench.analysis import allan  # noqa: E402,F401 - the bad import\n")
    r = lint_imports(tmp_path)
    assert r.returncode != 0
    assert "sims.platform -> bench.analysis.allan" in r.stdout


def test_the_cycle_count_sees_a_cycle(tmp_path: Path, monkeypatch) -> None:
    _copy_tree(tmp_path)
    with open(tmp_path / "bench" / "core" / "plan.py", "a") as f:
        f.write("\n\ndef _late() -> None:\n    from bench.core.engine import Abort  # noqa: F401\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    for name in [m for m in sys.modules if m.split(".")[0] in PACKAGES]:
        monkeypatch.delitem(sys.modules, name)
    cycles = import_cycles()
    assert any("bench.core.plan" in c and "bench.core.engine" in c for c in cycles), cycles


def test_the_layers_contract_names_packages_in_a_few_lines() -> None:
    """bench/ is arranged so its subpackages are the layers (issue 25): the contract lists
    packages, at most 8 lines, none a single module where its package would do."""
    import tomllib
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
    layers = next(c["layers"] for c in config["contracts"] if c["type"] == "layers")
    assert 3 <= len(layers) <= 8, layers
    for line in layers:
        for name in (n.strip() for n in line.replace("|", ":").split(":")):
            package = ROOT.joinpath(*name.split("."))
            assert (package / "__init__.py").is_file(), f"{name} is not a package"
    flat = [p.name for p in (ROOT / "bench").glob("*.py")
            if p.name not in {"__init__.py", "__main__.py"}]
    assert flat == [], f"modules outside the layer packages: {flat}"


# -- issue 25: bench/ names no procedure kind ------------------------------------------------

#: a kind's name as code would write it: the two shipped kinds' names (either spelling),
#: their procedure IDs, and "ladder" standing alone in a name or text
KIND_NAMES = re.compile(r"rate[-_ ]?ladder|drift[-_ ]?pulse|(?<![a-z])ladder(?![a-z])|"
                        r"RB-RL|RB-DP", re.IGNORECASE)


def kind_names_in(source: str, filename: str = "<source>") -> list[tuple[int, str]]:
    """(line, text) of every identifier, import and string in `source` that names a kind.
    Docstrings and comments may say what the code serves; code may not name it."""
    tree = ast.parse(source, filename)
    docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                  if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef
                                | ast.AsyncFunctionDef)
                  and node.body and isinstance(node.body[0], ast.Expr)
                  and isinstance(node.body[0].value, ast.Constant)}
    found = []
    for node in ast.walk(tree):
        texts: list[str] = []
        if isinstance(node, ast.Constant) and isinstance(node.value, str) \
                and id(node) not in docstrings:
            texts.append(node.value)
        elif isinstance(node, ast.Name):
            texts.append(node.id)
        elif isinstance(node, ast.Attribute):
            texts.append(node.attr)
        elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            texts.append(node.name)
        elif isinstance(node, ast.arg):
            texts.append(node.arg)
        elif isinstance(node, ast.keyword) and node.arg:
            texts.append(node.arg)
        elif isinstance(node, ast.alias):
            texts += [node.name, node.asname or ""]
        elif isinstance(node, ast.ImportFrom):
            texts.append(node.module or "")
        found += [(getattr(node, "lineno", 0), t) for t in texts if KIND_NAMES.search(t)]
    return found


def test_the_scan_sees_a_kind_named_in_code() -> None:
    source = ('"""Serves the rate ladder (a docstring may say so)."""\n'
              'from procedures.rate_ladder import KIND\n'
              'LADDER_COLUMNS = 1\n'
              'def f(drift_pulse=None):\n    """Nor here: drift-pulse."""\n'
              '    return {"procedure": "drift-pulse"}.get("x", RB_XY)\n'
              'x = g(ladder=1)\n')
    assert sorted(line for line, _ in kind_names_in(source)) == [2, 3, 4, 6, 7]
    assert {t for _, t in kind_names_in(source)} >= {"procedures.rate_ladder", "LADDER_COLUMNS",
                                                    "drift_pulse", "drift-pulse", "ladder"}


def test_no_module_under_bench_names_a_procedure_kind() -> None:
    """Every kind feeds every consumer through its interface (bench/core/registry.py): nothing
    in bench/ names a kind or guesses one, so a third kind is served like the first two."""
    found = []
    for path in sorted((ROOT / "bench").rglob("*.py")):
        rel = path.relative_to(ROOT)
        if KIND_NAMES.search(str(rel)):
            found.append(f"{rel}: the module's own name")
        found += [f"{rel}:{line}: {text[:70]!r}"
                  for line, text in kind_names_in(path.read_text(encoding="utf-8"), str(rel))]
    assert found == [], "\n".join(found)
