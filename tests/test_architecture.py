"""The import contract (pyproject.toml, `lint-imports`): layers import downwards only, no
import cycles, and the contract really fails when a lower layer imports a higher one.

These run the real tool on the real source tree (and on a copy with one bad import
added), the way CI does.
"""

from __future__ import annotations

import os
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
        f.write("\nfrom bench.engine import Abort  # noqa: E402,F401 - the bad import\n")
    r = lint_imports(tmp_path)
    assert r.returncode != 0
    assert "Layers import downwards only BROKEN" in r.stdout
    assert "drivers.units -> bench.engine" in r.stdout


def test_the_contract_fails_when_a_twin_imports_the_analysis(tmp_path: Path) -> None:
    _copy_tree(tmp_path)
    with open(tmp_path / "sims" / "platform.py", "a") as f:
        f.write("\nfrom bench.analysis import allan  # noqa: E402,F401 - the bad import\n")
    r = lint_imports(tmp_path)
    assert r.returncode != 0
    assert "sims.platform -> bench.analysis.allan" in r.stdout


def test_the_cycle_count_sees_a_cycle(tmp_path: Path, monkeypatch) -> None:
    _copy_tree(tmp_path)
    with open(tmp_path / "bench" / "plan.py", "a") as f:
        f.write("\n\ndef _late() -> None:\n    from bench.engine import Abort  # noqa: F401\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    for name in [m for m in sys.modules if m.split(".")[0] in PACKAGES]:
        monkeypatch.delitem(sys.modules, name)
    cycles = import_cycles()
    assert any("bench.plan" in c and "bench.engine" in c for c in cycles), cycles
