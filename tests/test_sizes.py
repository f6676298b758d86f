"""Issue 61 item 4: no function over 80 lines and no class over 500 lines in bench/,
drivers/, procedures/ and sims/, so that each stays one thing a reader can hold.

A size is `end_lineno - lineno + 1` of the def or class statement as Python's ast reports
it (decorators excluded, the docstring and comments inside included). Every offender is
named file:line:name with its size, so a failure says where to cut.
"""

from __future__ import annotations

import ast
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("bench", "drivers", "procedures", "sims")
MAX_FUNCTION_LINES = 80
MAX_CLASS_LINES = 500

#: offenders allowed, as "path:name": none (issue 61's item 4 is done). An entry that no
#: longer offends fails the test below, so a list added here cannot outlive its reason.
ALLOWED: frozenset[str] = frozenset()


def oversized(root: Path, packages: tuple[str, ...] = PACKAGES
              ) -> list[tuple[str, int, str, int, int]]:
    """Every function over MAX_FUNCTION_LINES and class over MAX_CLASS_LINES under the
    packages: (path relative to root, line, name, lines, the limit it is over)."""
    out = []
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
            rel = path.relative_to(root).as_posix()
            for node in ast.walk(tree):
                if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                    limit = MAX_FUNCTION_LINES
                elif isinstance(node, ast.ClassDef):
                    limit = MAX_CLASS_LINES
                else:
                    continue
                size = (node.end_lineno or node.lineno) - node.lineno + 1
                if size > limit:
                    out.append((rel, node.lineno, node.name, size, limit))
    return out


def _shown(found: list[tuple[str, int, str, int, int]]) -> str:
    return "\n".join(f"{rel}:{line}:{name} {size} lines (limit {limit})"
                     for rel, line, name, size, limit in found)


def test_no_function_over_80_lines_and_no_class_over_500() -> None:
    found = oversized(ROOT)
    print("over the size limits (* allowed for now):")
    for entry in found:
        print(("* " if f"{entry[0]}:{entry[2]}" in ALLOWED else "  ") + _shown([entry]))
    new = [f for f in found if f"{f[0]}:{f[2]}" not in ALLOWED]
    assert not new, "split these (issue 61 item 4):\n" + _shown(new)
    stale = ALLOWED - {f"{rel}:{name}" for rel, _, name, _, _ in found}
    assert not stale, ("no longer over the limits: remove from ALLOWED in "
                       f"tests/test_sizes.py: {sorted(stale)}")


def test_the_check_finds_a_long_function_and_a_long_class(tmp_path: Path) -> None:
    """The walker itself: a planted 81-line function and 501-line class are named with
    their file, line and size; 80 and 500 lines pass."""
    body = "\n".join(f"    x{i} = {i}" for i in range(79))
    long_fn = f"def long_one() -> None:\n{body}\n    x = 0\n"        # 81 lines
    ok_fn = f"def ok_one() -> None:\n{body}\n"                      # 80 lines
    methods = "\n".join(f"    a{i} = {i}" for i in range(499))
    long_cls = f"class Long:\n{methods}\n    b = 0\n"               # 501 lines
    ok_cls = f"class Fine:\n{methods}\n"                            # 500 lines
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "sub" / "m.py").write_text("\n" + long_fn + "\n\n" + ok_fn)
    (pkg / "c.py").write_text(textwrap.dedent(long_cls) + "\n\n" + ok_cls)
    found = oversized(tmp_path, ("pkg",))
    assert found == [("pkg/c.py", 1, "Long", 501, MAX_CLASS_LINES),
                     ("pkg/sub/m.py", 2, "long_one", 81, MAX_FUNCTION_LINES)]
    assert "pkg/sub/m.py:2:long_one 81 lines (limit 80)" in _shown(found)
