"""Annotations naming `object` outside the codecs and the YAML loader (issue 60: below 60).

An annotation `object` (or `dict[str, object]`, `list[object]`, an alias of one) says "some
value, look inside and see": every reader then narrows it with isinstance checks of its
own, which is how the result's typing stayed nominal before issue 60. Where JSON or YAML
becomes typed values (the codecs of tests/json_boundary.py, the YAML loader's schema walk)
an untyped value is the input and `object` is honest; everywhere else a value has a type.
This test counts, over bench/, drivers/, procedures/ and sims/, every parameter, return
and annotated assignment (class fields included) whose annotation names `object` or a
module-level alias of it, and holds the total to a budget that may only go down.
"""

from __future__ import annotations

import ast
from collections import Counter
from collections.abc import Iterable
from pathlib import Path

from tests.json_boundary import (
    CODECS,
    ROOT,
    SCANNED,
    YAML_LOADER,
    alias_closure,
    python_files,
)

#: today's total outside CODECS and YAML_LOADER (issue 60's goal: below 60); lower it when
#: the count falls, never raise it
BUDGET = 38


def object_aliases(modules: Iterable[tuple[str, ast.Module]]) -> frozenset[str]:
    """`object` and every module-level alias whose value names it (to a fixed point)."""
    return alias_closure(modules, ("object",), names_any)


def names_any(node: ast.expr, names: frozenset[str] | set[str]) -> bool:
    """Does the annotation name one of `names` (as a name, a string or inside one)?"""
    for n in ast.walk(node):
        if isinstance(n, ast.Name) and n.id in names:
            return True
        if isinstance(n, ast.Constant) and isinstance(n.value, str):
            try:
                inner = ast.parse(n.value, mode="eval").body
            except SyntaxError:
                continue
            if names_any(inner, names):
                return True
    return False


def annotations_of(tree: ast.Module) -> Iterable[ast.expr]:
    """Every parameter, return and annotated-assignment annotation of the module."""
    for n in ast.walk(tree):
        if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef):
            a = n.args
            for x in [*a.posonlyargs, *a.args, *a.kwonlyargs,
                      *([a.vararg] if a.vararg else []), *([a.kwarg] if a.kwarg else [])]:
                if x.annotation is not None:
                    yield x.annotation
            if n.returns is not None:
                yield n.returns
        elif isinstance(n, ast.AnnAssign):
            yield n.annotation


def count(root: Path = ROOT) -> Counter[str]:
    """Per file outside CODECS and YAML_LOADER: annotations naming `object` (or an alias)."""
    modules = list(python_files(root, SCANNED))
    names = object_aliases(modules)
    out: Counter[str] = Counter()
    for path, tree in modules:
        if path in CODECS or path in YAML_LOADER:
            continue
        for ann in annotations_of(tree):
            if names_any(ann, names):
                out[path] += 1
    return out


def test_object_annotations_within_budget() -> None:
    found = count()
    total = sum(found.values())
    worst = ", ".join(f"{p} {n}" for p, n in found.most_common(8))
    assert total <= BUDGET, (
        f"{total} annotations name `object` outside the codecs and the YAML loader, "
        f"budget {BUDGET} (issue 60: below 60); most in: {worst}. Give the value its type "
        "(a msgspec Struct decoded in a codec, a Protocol, a union), not `object`.")


def test_planted_object_annotations_are_counted(tmp_path: Path) -> None:
    """The scanner finds each form a planted module uses, and only those."""
    pkg = tmp_path / "bench" / "report" / "dcc"
    pkg.mkdir(parents=True)
    for d in SCANNED:
        (tmp_path / d).mkdir(exist_ok=True)
    (pkg / "planted.py").write_text(
        "from typing import TypeAlias\n"
        "Loose: TypeAlias = dict[str, object]\n"
        "Looser = list[Loose]\n"
        "def a(x: object) -> int: ...\n"                 # 1
        "def b(x: int) -> 'Looser': ...\n"               # 2 (alias of an alias, quoted)
        "class C:\n"
        "    f: Loose\n"                                 # 3
        "    g: int\n"
        "def c(*args: object, **kw: int) -> None: ...\n"  # 4
        "def d(x: int, y: str) -> float: ...\n",
        encoding="utf-8")
    assert count(tmp_path) == Counter({"bench/report/dcc/planted.py": 4})
