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
import pytest

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


def _docstring_ids(tree: ast.AST) -> set[int]:
    """The ids of the docstring nodes of `tree` (module, classes, functions): the guards
    below let prose name what code may not."""
    return {id(node.body[0].value) for node in ast.walk(tree)
            if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef
                          | ast.AsyncFunctionDef)
            and node.body and isinstance(node.body[0], ast.Expr)
            and isinstance(node.body[0].value, ast.Constant)}


def kind_names_in(source: str, filename: str = "<source>") -> list[tuple[int, str]]:
    """(line, text) of every identifier, import and string in `source` that names a kind.
    Docstrings and comments may say what the code serves; code may not name it."""
    tree = ast.parse(source, filename)
    docstrings = _docstring_ids(tree)
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


# -- issue 61: bench/ names no kind's quantities; the contracts name no kind ------------------

def kind_quantities() -> frozenset[str]:
    """What the installed kinds report, as code would name it: each declared figure's
    key, its result.json key and its U's key (either spelling, `_u` and `_U`), and the
    check values of the instruments a kind measures (one- and two-letter keys left out:
    `k` is also a colour)."""
    from bench.core.registry import procedure_names
    from bench.kind import ChecksInstruments, kind_of

    keys: set[str] = set()
    for name in procedure_names():
        records = kind_of(name).records
        for spec in records.figures:
            keys |= {spec.quantity, spec.path.split(".")[-1].removesuffix("[]")}
            if spec.u_path:
                keys |= {spec.u_path, spec.u_path.replace("_u_", "_U_")}
        if isinstance(records, ChecksInstruments):
            keys |= set(records.check_quantities)
    return frozenset(k for k in keys if len(k) > 2 and "<" not in k)


def quantities_in(source: str, keys: frozenset[str], filename: str = "<source>"
                  ) -> list[tuple[int, str]]:
    """(line, text) of every identifier and string in `source` (not its docstrings or
    comments) that is one of `keys`."""
    tree = ast.parse(source, filename)
    docstrings = _docstring_ids(tree)
    found = []
    for node in ast.walk(tree):
        text = (node.value if isinstance(node, ast.Constant) and isinstance(node.value, str)
                and id(node) not in docstrings else
                node.id if isinstance(node, ast.Name) else
                node.attr if isinstance(node, ast.Attribute) else
                node.arg if isinstance(node, ast.arg | ast.keyword) else None)
        if text in keys:
            found.append((getattr(node, "lineno", 0), text))
    return sorted(found)


def test_the_quantity_scan_sees_a_quantity_in_code() -> None:
    keys = frozenset({"w0_dps", "rate_error_U_rel"})
    source = ('"""Reads w0_dps (a docstring may say so)."""\n'
              'x = row.get("w0_dps")  # rate_error_U_rel in a comment\n'
              'y = row.rate_error_U_rel\n')
    assert quantities_in(source, keys) == [(2, "w0_dps"), (3, "rate_error_U_rel")]


#: where bench/ may write a kind's key, and why: nowhere now (the twins' truth, whose
#: ripple shares the result's words, is declared in sims/truth.py; result.json's `_U`/`_ustd`
#: twins are the kinds' model fields, so the naming rule lists no kind's key)
QUANTITY_NAMED: set[tuple[str, str]] = set()


def test_no_module_under_bench_names_a_kinds_quantity() -> None:
    """A kind's views (its station tables, its check values, its plots) live in its
    package: the station, the records, the certificate and the DCC read a kind's
    quantities through its parts (bench/kind), never by name. The analysis's maths
    (bench/analysis) computes them and is left out."""
    keys = kind_quantities()
    assert {"w0_dps", "rate_error_rel", "own_drift_dph", "noise_floor_dps"} <= keys
    found = [f"{rel}:{line}: {text!r}"
             for path in sorted((ROOT / "bench").rglob("*.py"))
             if "analysis" not in (rel := path.relative_to(ROOT)).parts
             for line, text in quantities_in(path.read_text(encoding="utf-8"), keys,
                                             str(path))
             if (str(rel), text) not in QUANTITY_NAMED]
    assert found == [], "\n".join(found)


def kind_event_tags() -> frozenset[str]:
    """The tags of the journal records the installed kinds declare (each kind's `events`
    module, loaded by the journal codec, bench/core/events.py)."""
    from bench.core import events as ev

    ev.declared("load every kind")
    found: list[type[ev.Event]] = []
    todo = [ev.Event]
    while todo:
        subs = todo.pop().__subclasses__()
        found += subs
        todo += subs
    return frozenset(ev.kind_of(c) for c in found if c.__module__.startswith("procedures.")
                     and ev.kind_of(c) and ev.kind_of(c) != c.__name__)


def strings_in(source: str, keys: frozenset[str], filename: str = "<source>"
               ) -> list[tuple[int, str]]:
    """(line, text) of every string in `source` (not its docstrings) that is one of `keys`
    (an event's tag is a string; a name such as `pair` or `acquire` is not one)."""
    tree = ast.parse(source, filename)
    docstrings = _docstring_ids(tree)
    return sorted((node.lineno, node.value) for node in ast.walk(tree)
                  if isinstance(node, ast.Constant) and isinstance(node.value, str)
                  and id(node) not in docstrings and node.value in keys)


def test_the_tag_scan_sees_a_tag_in_code() -> None:
    source = ('"""Shows the pair events (a docstring may say so)."""\n'
              'SHOWN = ("abort", "pair")\n'
              'pair = e.pair\n')
    assert strings_in(source, frozenset({"pair", "settled"})) == [(2, "pair")]


#: where bench/ may write a string equal to a kind's event tag, and why: the drive's raw
#: log's record kind (drivers/drive.py), a homonym of the ladder's `settled`
TAG_NAMED = {("bench/app/records/checks.py", "settled")}


def test_no_module_under_bench_names_a_kinds_event() -> None:
    """Which events the station shows, the fleet asks for and the log words is declared on
    each kind's records (`Event.STATION_LOG`, `log_text`, `live_rows`): bench/ writes no
    kind's event tag, so a plug-in kind's events are served like the shipped kinds'."""
    tags = kind_event_tags()
    assert {"pair", "pair_failed", "settled", "acquire", "cycle"} <= tags
    found = [f"{rel}:{line}: {text!r}"
             for path in sorted((ROOT / "bench").rglob("*.py"))
             for line, text in strings_in(path.read_text(encoding="utf-8"), tags, str(path))
             if (str(rel := path.relative_to(ROOT)), text) not in TAG_NAMED]
    assert found == [], "\n".join(found)


def test_the_import_contracts_name_no_kind_and_cover_every_kind() -> None:
    """The contracts in pyproject.toml name no kind: the kinds' independence covers every
    package under procedures/ by a wildcard, so a kind added there is held to it with no
    line of its own; and every installed kind shipped in procedures/ is such a package."""
    import tomllib

    from bench.core.registry import kind_location, procedure_names

    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
    assert not KIND_NAMES.search(str(config)), config
    (independence,) = [c for c in config["contracts"] if c["type"] == "independence"]
    assert independence["modules"] == ["procedures.*"]
    shipped = [kind_location(n).partition(":")[0] for n in procedure_names()]
    assert len(shipped) >= 2 and all(re.fullmatch(r"procedures\.\w+(\.\w+)*", m)
                                     and m.split(".")[1] != "base" for m in shipped), shipped


# -- raw settings mappings (issue 25) ---------------------------------------------------
#
# The procedure and stand files are validated, then parsed once into frozen objects
# (bench/core/config.py's StandSettings, each kind's `parse`). Below the loader nothing reads
# the raw mappings by key: a key read there is a default written twice or a key the
# schema never validated. This walks the source and follows the raw mappings: from
# where they enter (a Config's `stand`/`procedure`, `Config.stand_axis`, the YAML
# documents' `.data`, SimBench's stand copy) through every name, attribute, argument and
# return value they are bound to, and reports each key access on one (`m[k]`, `m.get`,
# `k in m`, `m.pop`/`setdefault`/`update`) outside the files that parse them.

#: the files that turn the raw mappings into settings (the loader, the schema and the
#: kinds' own settings parsers)
PARSERS = ("bench/core/config.py", "bench/core/schema.py", "bench/core/loader.py", "bench/core/yamlfile.py")
PARSER_GLOB = "procedures/*/settings.py"
RAW_ATTRS = {"stand", "procedure"}            # Config's raw mappings...
RAW_OWNERS = ("cfg", "config")                # ...on a name ending thus (cfg, self.cfg)
RAW_CALLS = {"stand_axis"}                    # methods returning a raw stand mapping
KEY_METHODS = {"get", "pop", "setdefault", "update", "__getitem__", "__contains__"}
PASS_METHODS = {"get", "copy", "pop", "setdefault"}      # a part of a raw mapping is raw
ITER_METHODS = {"items", "values"}
COPIES = {"deepcopy", "copy", "dict", "MappingProxyType"}
#: list, set and dict methods: a call of one is never taken for our class's namesake
CONTAINER_METHODS = {"append", "extend", "add", "insert", "update", "remove", "discard",
                     "clear", "keys", "items", "values", "index", "count", "sort"}


def _mapping_keys() -> frozenset[str]:
    """The keys whose values are mappings or lists in some stand or procedure file (from
    the schemas): `stand["axes"]` is a raw mapping, `drive["node_id"]` a number."""
    from bench.core.loader import any_stand_schema
    from bench.core.registry import procedure_kind, procedure_names
    from bench.core.schema import Any_, Check, ListOf, Map, MapOf, Node, OneOf

    out: set[str] = set()

    def nested(node: Node) -> bool:
        if isinstance(node, Check):
            return nested(node.inner)
        if isinstance(node, OneOf):
            return any(nested(o) for o in node.options)
        return isinstance(node, Map | MapOf | ListOf | Any_)

    def walk(node: Node) -> None:
        if isinstance(node, Check):
            walk(node.inner)
        elif isinstance(node, OneOf):
            for o in node.options:
                walk(o)
        elif isinstance(node, MapOf | ListOf):
            walk(node.value if isinstance(node, MapOf) else node.item)
        elif isinstance(node, Map):
            for k, key in node.keys.items():
                if nested(key.node):
                    out.add(k)
                walk(key.node)

    walk(any_stand_schema())
    for name in procedure_names():
        walk(procedure_kind(name).settings.procedure_schema())
    return frozenset(out)


MAPPING_KEYS = _mapping_keys()


def _holds_mapping(key: ast.AST) -> bool:
    """A subscript of a raw mapping by `key` is raw too unless the key names a scalar."""
    if isinstance(key, ast.Constant):
        return not isinstance(key.value, str) or key.value in MAPPING_KEYS
    return not isinstance(key, ast.Slice)


def _name_of(node: ast.AST) -> str:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return node.attr
    return ""


def _functions(tree: ast.AST) -> list[ast.FunctionDef | ast.AsyncFunctionDef]:
    return [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef)]


class _RawFlow:
    """Where the raw mappings go, found by iterating to a fixed point over every function:
    its tainted locals, the parameters callers pass raw mappings to, the functions that
    return one and the attributes one is stored in."""

    def __init__(self, modules: dict[str, ast.Module]) -> None:
        self.modules = modules
        self.params: set[tuple[int, str]] = set()     # (function's id, parameter name)
        self.returns: set[int] = set()                # functions returning a raw mapping
        self.cls: str | None = None                   # the class of the function walked
        self.attrs: set[str] = set()                  # attributes holding one (self.x = raw)
        # callees by name: module functions, each class's methods (its __init__ under
        # the class's name), and methods by name where only one class defines that name
        self.functions: dict[str, list[ast.FunctionDef | ast.AsyncFunctionDef]] = {}
        self.methods: dict[tuple[str, str], list[ast.FunctionDef | ast.AsyncFunctionDef]] = {}
        by_name: dict[str, list[ast.FunctionDef | ast.AsyncFunctionDef]] = {}
        self.owner: dict[int, str] = {}
        self.module_of: dict[int, int] = {}    # function -> its module
        self.module: int | None = None          # the module of the function walked
        for tree in modules.values():
            for node in ast.walk(tree):
                if isinstance(node, ast.ClassDef):
                    for f in node.body:
                        if isinstance(f, ast.FunctionDef | ast.AsyncFunctionDef):
                            self.methods.setdefault((node.name, f.name), []).append(f)
                            by_name.setdefault(f.name, []).append(f)
                            self.owner[id(f)] = node.name
                            if f.name == "__init__":
                                self.functions.setdefault(node.name, []).append(f)
            for f in tree.body:
                if isinstance(f, ast.FunctionDef | ast.AsyncFunctionDef):
                    self.functions.setdefault(f.name, []).append(f)
            for f in _functions(tree):
                self.module_of[id(f)] = id(tree)
        # a method called on an object of unknown class: the one class defining it, or
        # every procedure kind for the plug-in interface's methods (bench/core/registry.py)
        protocol = {f.name for c, f in self._class_methods("bench/core/registry.py")
                    if c == "ProcedureKind"}
        self.by_name = {k: v for k, v in by_name.items()
                        if (len(v) == 1 and k not in CONTAINER_METHODS) or k in protocol}
        self.classes = {c for c, _ in self.methods}
        self.types: dict[str, str] = {}   # locals made by a class's constructor

    def _class_methods(self, path: str) -> list[tuple[str, ast.FunctionDef
                                                      | ast.AsyncFunctionDef]]:
        tree = self.modules.get(path)
        return [(c.name, f) for c in (tree.body if tree else []) if isinstance(c, ast.ClassDef)
                for f in c.body if isinstance(f, ast.FunctionDef | ast.AsyncFunctionDef)]

    def callees(self, call: ast.Call, cls: str | None) -> list[ast.FunctionDef
                                                              | ast.AsyncFunctionDef]:
        f = call.func
        if isinstance(f, ast.Name):   # this module's own function of that name, if any
            found = self.functions.get(f.id, [])
            own = [fn for fn in found if self.module_of.get(id(fn)) == self.module]
            return own or found
        if not isinstance(f, ast.Attribute):
            return []
        base = _name_of(f.value)
        if base in ("self", "cls") and cls is not None:
            return self.methods.get((cls, f.attr), [])
        base = self.types.get(base, base)
        if base in self.classes:
            return self.methods.get((base, f.attr), [])
        return [*self.functions.get(f.attr, []), *self.by_name.get(f.attr, [])]

    def raw(self, node: ast.AST | None, local: set[str]) -> bool:
        if node is None:
            return False
        if isinstance(node, ast.Name):
            return node.id in local
        if isinstance(node, ast.Attribute):
            if node.attr in RAW_ATTRS and _name_of(node.value).lower().endswith(RAW_OWNERS):
                return True
            if node.attr == "data" and _name_of(node.value).endswith(("stand_doc",
                                                                       "procedure_doc")):
                return True
            return node.attr in self.attrs
        if isinstance(node, ast.Subscript):
            return self.raw(node.value, local) and _holds_mapping(node.slice)
        if isinstance(node, ast.BoolOp):
            return any(self.raw(v, local) for v in node.values)
        if isinstance(node, ast.IfExp):
            return self.raw(node.body, local) or self.raw(node.orelse, local)
        if isinstance(node, ast.NamedExpr):
            return self.raw(node.value, local)
        if isinstance(node, ast.Tuple | ast.List):
            return any(self.raw(e, local) for e in node.elts)
        if isinstance(node, ast.Dict):
            return any(k is None and self.raw(v, local) for k, v in zip(node.keys, node.values,
                                                                          strict=True))
        if isinstance(node, ast.Call):
            f = node.func
            if isinstance(f, ast.Attribute) and f.attr in PASS_METHODS \
                    and self.raw(f.value, local) and (f.attr == "copy" or not node.args
                                                      or _holds_mapping(node.args[0])):
                return True
            if _name_of(f) in RAW_CALLS:
                return True
            if _name_of(f) in COPIES and node.args and self.raw(node.args[0], local):
                return True
            return any(id(fn) in self.returns for fn in self.callees(node, self.cls))
        return False

    def _bind(self, target: ast.AST, local: set[str]) -> bool:
        """Mark what `target` names as raw; True when something new was marked."""
        if isinstance(target, ast.Name) and target.id not in local:
            local.add(target.id)
            return True
        if isinstance(target, ast.Attribute) and target.attr not in self.attrs \
                and target.attr not in RAW_ATTRS:
            self.attrs.add(target.attr)
            return True
        if isinstance(target, ast.Tuple | ast.List):
            return any([self._bind(e, local) for e in target.elts])
        if isinstance(target, ast.Starred):
            return self._bind(target.value, local)
        return False

    def _iterated_raw(self, it: ast.AST, local: set[str]) -> bool:
        """`for v in raw.values()` / `for k, v in raw.items()`: v is raw (a list in a raw
        mapping iterates into raw items too)."""
        if isinstance(it, ast.Call) and isinstance(it.func, ast.Attribute) \
                and it.func.attr in ITER_METHODS:
            return self.raw(it.func.value, local)
        if isinstance(it, ast.Call) and _name_of(it.func) == "enumerate" and it.args:
            return self.raw(it.args[0], local)
        return self.raw(it, local) and not isinstance(it, ast.Name | ast.Attribute)

    def local_raw(self, fn: ast.FunctionDef | ast.AsyncFunctionDef) -> tuple[set[str], bool]:
        """The names in `fn` bound to raw mappings; and whether anything global changed."""
        args = [*fn.args.posonlyargs, *fn.args.args, *fn.args.kwonlyargs]
        self.cls = self.owner.get(id(fn))
        self.module = self.module_of.get(id(fn))
        self.types = {t.id: n.value.func.id for n in ast.walk(fn) if isinstance(n, ast.Assign)
                      and isinstance(n.value, ast.Call) and isinstance(n.value.func, ast.Name)
                      and n.value.func.id in self.classes
                      for t in n.targets if isinstance(t, ast.Name)}
        local = {a.arg for a in args if (id(fn), a.arg) in self.params}
        attrs_before = len(self.attrs)
        changed = True
        while changed:
            changed = False
            for node in ast.walk(fn):
                if isinstance(node, ast.Assign) and self.raw(node.value, local):
                    for t in node.targets:
                        changed |= self._bind(t, local)
                elif isinstance(node, ast.AnnAssign | ast.AugAssign | ast.NamedExpr) \
                        and self.raw(node.value, local):
                    changed |= self._bind(node.target, local)
                elif isinstance(node, ast.For | ast.comprehension) \
                        and self._iterated_raw(node.iter, local):
                    t = node.target
                    # items(): the key is a name, the value raw
                    if isinstance(t, ast.Tuple) and isinstance(node.iter, ast.Call) \
                            and _name_of(node.iter.func) in ("items", "enumerate") \
                            and len(t.elts) == 2:
                        t = t.elts[1]
                    changed |= self._bind(t, local)
                elif isinstance(node, ast.With):
                    for item in node.items:
                        if item.optional_vars is not None and self.raw(item.context_expr,
                                                                       local):
                            changed |= self._bind(item.optional_vars, local)
        changed_global = len(self.attrs) != attrs_before
        for node in ast.walk(fn):
            if isinstance(node, ast.Return) and self.raw(node.value, local) \
                    and id(fn) not in self.returns:
                self.returns.add(id(fn))
                changed_global = True
            if isinstance(node, ast.Call):
                changed_global |= self._pass(node, local)
        return local, changed_global

    def _pass(self, call: ast.Call, local: set[str]) -> bool:
        """A raw mapping passed as an argument makes the callee's parameter raw."""
        if _name_of(call.func) in KEY_METHODS | PASS_METHODS | COPIES:
            return False
        changed = False
        for fn in self.callees(call, self.cls):
            params = [a.arg for a in [*fn.args.posonlyargs, *fn.args.args]]
            if params and params[0] in ("self", "cls"):
                params = params[1:]
            for i, arg in enumerate(call.args):
                if i < len(params) and self.raw(arg, local) \
                        and (id(fn), params[i]) not in self.params:
                    self.params.add((id(fn), params[i]))
                    changed = True
            for kw in call.keywords:
                if kw.arg and self.raw(kw.value, local) and (id(fn), kw.arg) not in self.params:
                    self.params.add((id(fn), kw.arg))
                    changed = True
        return changed

    def solve(self) -> None:
        changed = True
        while changed:
            changed = False
            for tree in self.modules.values():
                for fn in _functions(tree):
                    changed |= self.local_raw(fn)[1]

    def accesses(self, path: str, root: Path = ROOT) -> list[str]:
        """Each key access on a raw mapping in module `path`: 'path:line: source'."""
        out: set[tuple[int, str]] = set()
        tree = self.modules[path]
        src = (root / path).read_text().splitlines()
        for fn in _functions(tree):
            local = self.local_raw(fn)[0]
            for node in ast.walk(fn):
                hit = (isinstance(node, ast.Subscript) and self.raw(node.value, local)) or (
                    isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                    and node.func.attr in KEY_METHODS and self.raw(node.func.value, local)) or (
                    isinstance(node, ast.Compare) and any(
                        isinstance(op, ast.In | ast.NotIn) and self.raw(c, local)
                        for op, c in zip(node.ops, node.comparators, strict=True)))
                if hit:
                    line = getattr(node, "lineno", 0)
                    out.add((line, f"{path}:{line}: {src[line - 1].strip()}"))
        return [text for _, text in sorted(out)]


def _parsers() -> set[str]:
    return {*PARSERS, *(str(p.relative_to(ROOT)) for p in ROOT.glob(PARSER_GLOB))}


def raw_mapping_accesses(root: Path = ROOT) -> list[str]:
    """Every key access on a raw stand or procedure mapping outside the parsers."""
    modules = {str(p.relative_to(root)): ast.parse(p.read_text(), str(p))
               for pkg in PACKAGES for p in sorted((root / pkg).rglob("*.py"))}
    flow = _RawFlow(modules)
    flow.solve()
    skip = _parsers()
    return [hit for path in modules if path not in skip for hit in flow.accesses(path, root)]


def test_nothing_below_the_loader_reads_a_raw_stand_or_procedure_mapping() -> None:
    found = raw_mapping_accesses()
    assert found == [], f"{len(found)} key accesses on raw mappings:\n" + "\n".join(found)


def test_the_raw_mapping_walk_sees_an_access(tmp_path: Path) -> None:
    """The walk above finds accesses through a name, a call's parameter and a return."""
    for pkg in PACKAGES:
        (tmp_path / pkg).mkdir()
    (tmp_path / "bench" / "x.py").write_text(
        "def outer(cfg):\n"
        "    s = cfg.stand\n"
        "    inner(s['axes'])\n"
        "    return fogs(cfg)\n"
        "def inner(axes):\n"
        "    for name, spec in axes.items():\n"
        "        print(spec.get('drive'))\n"
        "def fogs(cfg):\n"
        "    return cfg.stand_axis('outer')\n"
        "def user(cfg):\n"
        "    f = fogs(cfg)\n"
        "    ok = cfg.stand_settings.axes['outer']\n"
        "    return 'fog' in f, ok.fog\n")
    found = raw_mapping_accesses(tmp_path)
    assert [h.split(":")[1] for h in found] == ["3", "7", "13"], found


# -- the run directory's layout, spelled in one module (issue 45) ------------------------
#
# Every path inside a run directory comes from bench/core/rundir_layout.py (or RunDir,
# which uses it). A file name of the layout written anywhere else is a second spelling
# that a change of the layout would miss.

LAYOUT_MODULE = "bench/core/rundir_layout.py"
#: names that only ever mean a run directory's files
LAYOUT_NAMES = frozenset({"events.jsonl", "result.json", "meta.json", "certificate.html",
                          "certificate.pdf", "certificate.dcc.xml",
                          "certificate.dcc.invalid.xml"})
#: a raw capture's name ends thus (`f"{axis}-fog.bin"`)
LAYOUT_SUFFIXES = ("-fog.bin", "-counter.jsonl", "-drive.jsonl", "-dmm.jsonl")
#: folder names of the layout, counted where they are joined into a path (`run / "raw"`):
#: "raw" is also a word of the SCPI twins, "issued" one of the register's states; the
#: input copies' names (procedure.yaml, ...) also name `bench init`'s starter files
LAYOUT_FOLDERS = frozenset({"raw", "issued", "procedure.yaml", "stand.yaml", "lab.yaml"})
#: `bench init` writes its starter files, named as a run directory's copies, into the
#: user's folder: not a run directory
LAYOUT_EXEMPT = frozenset({"bench/app/starter.py"})


def _docstring_ids(tree: ast.AST) -> set[int]:
    return {id(node.body[0].value) for node in ast.walk(tree)
            if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef
                          | ast.AsyncFunctionDef)
            and node.body and isinstance(node.body[0], ast.Expr)
            and isinstance(node.body[0].value, ast.Constant)}


def layout_literals(source: str, filename: str = "<source>") -> list[tuple[int, str]]:
    """(line, text) of every string in `source` that spells a part of the run directory's
    layout: a layout file's name, a `raw/...` path, a raw capture's suffix, or a layout
    folder joined into a path with `/`. Docstrings and comments may describe the layout."""
    tree = ast.parse(source, filename)
    docstrings = _docstring_ids(tree)
    joined = {id(side) for node in ast.walk(tree)
              if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div)
              for side in (node.left, node.right)}
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Constant) or not isinstance(node.value, str) \
                or id(node) in docstrings:
            continue
        text = node.value
        if (text in LAYOUT_NAMES or text.startswith("raw/") or text.endswith(LAYOUT_SUFFIXES)
                or (text in LAYOUT_FOLDERS and id(node) in joined)):
            found.append((node.lineno, text))
    return found


def layout_spellings(root: Path = ROOT) -> dict[str, list[str]]:
    """Per file (outside the layout module): the layout names it spells."""
    out: dict[str, list[str]] = {}
    for pkg in PACKAGES:
        for path in sorted((root / pkg).rglob("*.py")):
            rel = path.relative_to(root).as_posix()
            if rel == LAYOUT_MODULE or rel in LAYOUT_EXEMPT:
                continue
            hits = layout_literals(path.read_text(encoding="utf-8"), rel)
            if hits:
                out[rel] = [f"{rel}:{line}: {text!r}" for line, text in hits]
    return out


def test_the_run_directory_layout_is_spelled_in_one_module() -> None:
    found = [hit for hits in layout_spellings().values() for hit in hits]
    assert found == [], ("spelled outside bench/core/rundir_layout.py:\n" + "\n".join(found))


def test_the_layout_scan_sees_a_planted_raw_path(tmp_path: Path) -> None:
    """Not blind: a `"raw/"` path, a layout file's name, a capture's suffix or a folder
    joined into a path, planted in a module, is found; the layout module itself and
    docstrings are not."""
    for pkg in PACKAGES:
        (tmp_path / pkg).mkdir()
    (tmp_path / "bench" / "core").mkdir()
    (tmp_path / "bench" / "core" / "rundir_layout.py").write_text('RAW = "raw"\n')
    (tmp_path / "procedures" / "x.py").write_text(
        '"""Reads raw/s1/x-fog.bin and result.json (a docstring may say so)."""\n'
        'def capture(run, k, axis):\n'
        '    a = run / f"raw/s{k}/{axis}-fog.bin"\n'
        '    b = run / "raw" / f"s{k}" / f"{axis}-counter.jsonl"\n'
        '    return a, b, run / "result.json", {"raw": 1}\n')
    found = layout_spellings(tmp_path)
    assert list(found) == ["procedures/x.py"]
    assert sorted(h.split(":", 1)[1] for h in found["procedures/x.py"]) == [
        "3: '-fog.bin'", "3: 'raw/s'", "4: '-counter.jsonl'", "4: 'raw'", "5: 'result.json'"]


# -- `Any` in annotations (issue 45: below 200 is the goal; counted, not yet asserted) ----

def _annotations(tree: ast.AST) -> list[ast.expr]:
    """Every annotation of a module: parameters, returns, annotated assignments."""
    out: list[ast.expr] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            args = node.args
            for a in (*args.posonlyargs, *args.args, *args.kwonlyargs,
                      *(x for x in (args.vararg, args.kwarg) if x is not None)):
                if a.annotation is not None:
                    out.append(a.annotation)
            if node.returns is not None:
                out.append(node.returns)
        elif isinstance(node, ast.AnnAssign):
            out.append(node.annotation)
    return out


def _is_any(node: ast.AST, aliases: set[str]) -> bool:
    return ((isinstance(node, ast.Name) and (node.id == "Any" or node.id in aliases))
            or (isinstance(node, ast.Attribute) and node.attr == "Any"))


def any_aliases(tree: ast.Module) -> set[str]:
    """Module-level names bound to `Any` itself (`Json = Any`, `Json: TypeAlias = Any`)."""
    out: set[str] = set()
    for node in tree.body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1 \
                and isinstance(node.targets[0], ast.Name) and _is_any(node.value, set()):
            out.add(node.targets[0].id)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) \
                and node.value is not None and _is_any(node.value, set()):
            out.add(node.target.id)
    return out


def any_in_annotations(source: str, filename: str = "<source>") -> int:
    """How many times `Any` (or a module's alias of it) is named inside the annotations of
    `source`; a string annotation is parsed and counted too."""
    tree = ast.parse(source, filename)
    aliases = any_aliases(tree)
    count = 0
    for ann in _annotations(tree):
        for node in ast.walk(ann):
            if isinstance(node, ast.Constant) and isinstance(node.value, str):
                try:
                    inner = ast.parse(node.value, mode="eval")
                except SyntaxError:
                    continue
                count += sum(_is_any(n, aliases) for n in ast.walk(inner))
            elif _is_any(node, aliases):
                count += 1
    return count


def any_count(root: Path = ROOT) -> dict[str, int]:
    """Per package: the `Any` names inside annotations (bench/, drivers/, procedures/, sims/)."""
    return {pkg: sum(any_in_annotations(p.read_text(encoding="utf-8"), str(p))
                     for p in sorted((root / pkg).rglob("*.py")))
            for pkg in PACKAGES}


def test_the_any_count_counts_annotations_only() -> None:
    source = ("from typing import Any\nimport typing\nJson = Any\nRow = dict[str, int]\n"
              "def f(a: Any, b: dict[str, Any], *c: Json, **d: 'list[Any]') -> typing.Any:\n"
              "    x: Json = g(Any)\n    return cast(Any, x)\n"
              "class C:\n    y: Row\n    z: tuple[Any, Any] = ()\n")
    assert any_in_annotations(source) == 8


#: issue 45 asks for fewer than 200; 740 at a057f73, 75 now (the station's and the records'
#: reads of CONTRACT §3's axes typed through the ladder's axes view, now
#: procedures/rate_ladder/axes_view.py; the ladder's analysis writing through its result
#: module). A ratchet: lower it when the count falls, never raise
#: it
ANY_CEILING = 75


def test_any_in_annotations_stays_below_the_ceiling(capsys: pytest.CaptureFixture[str]
                                                    ) -> None:
    counts = any_count()
    total = sum(counts.values())
    with capsys.disabled():
        print(f"\nAny in annotations: {total} ({counts})")
    assert 0 < total <= ANY_CEILING < 200, counts
