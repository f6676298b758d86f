"""Where JSON meets the code (issue 60): the scanner behind tests/test_json_boundary.py.

A typed result model per kind is decoded from JSON in its codec module and read by
attributes everywhere else; so outside the codecs nothing should read JSON or pass a JSON
map around. Per file this counts, following code rather than names:
- `json_reads`: calls of `json.load`/`json.loads`, and of the project's own JSON readers: a
  function that calls one of those (directly or through another reader) and returns a JSON
  map (`read_json_object`, `read_jsonl`...), found by walking the code, not by a list;
- `json_map_signatures`: functions whose parameters or return name `Mapping[str, object]`,
  `dict[str, object]`, `JsonObject`, or a type alias the code defines as one of them.

python -m tests.json_boundary prints today's counts in the form of json_boundary_allowed.py.
"""

from __future__ import annotations

import ast
import functools
import json
from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: the layers scanned
SCANNED = ("bench", "drivers", "procedures", "sims")
#: modules whose work is to turn JSON into typed values and back (may read JSON, pass maps)
CODECS = frozenset({
    "bench/app/fleet/codec.py",
    "bench/app/impact_codec.py",
    "bench/app/records/codec.py",
    "bench/app/register/wire.py",
    "bench/core/events.py",
    "bench/core/journal_codec.py",
    "bench/core/settings_codec.py",
    "bench/report/budget_codec.py",
    "bench/report/certificate/sources.py",
    "bench/report/codec.py",
    "bench/report/result_frame.py",
    "procedures/drift_pulse/codec.py",
    "procedures/rate_ladder/codec.py",
})
#: the YAML loader (issue 60 exempts it with the codecs): the schema nodes check raw YAML
#: values, which arrive as maps, and the line-keeping loader builds them (untyped input is
#: what they exist to type); nothing below it reads a raw mapping
YAML_LOADER = frozenset({"bench/core/schema.py", "bench/core/yamlfile.py"})
#: the JSON map types (and aliases of them, which `aliases` adds)
JSON_MAPS = frozenset({"Mapping[str, object]", "dict[str, object]", "JsonObject"})
#: a JSON reader hidden behind `Any` is still one: a function returning these that reads
#: JSON is a reader too (its signature is not counted: the issue names the three above)
ANY_MAPS = frozenset({"Mapping[str, Any]", "dict[str, Any]"})

Counts = dict[str, dict[str, int]]
FunctionNode = ast.FunctionDef | ast.AsyncFunctionDef


def python_files(root: Path, dirs: Iterable[str] = SCANNED) -> Iterator[tuple[str, ast.Module]]:
    """(path relative to root, parsed module) of every .py file under `dirs`."""
    for d in dirs:
        for p in sorted((root / d).rglob("*.py")):
            yield p.relative_to(root).as_posix(), _parsed(p.read_text(encoding="utf-8"),
                                                          p.relative_to(root).as_posix())


@functools.cache
def _parsed(text: str, path: str) -> ast.Module:
    """One parse per file text and place: the guards scan the tree several times a session
    (their planted cases scan a copy of it), and parsing is most of their time. The trees
    are only read."""
    return ast.parse(text, path)


def _is_json_load(node: ast.AST) -> bool:
    return (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
            and node.func.attr in ("load", "loads") and isinstance(node.func.value, ast.Name)
            and node.func.value.id == "json")


def _functions(tree: ast.AST) -> Iterator[FunctionNode]:
    for n in ast.walk(tree):
        if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef):
            yield n


def _annotations(f: FunctionNode) -> list[ast.expr]:
    a = f.args
    args = [*a.posonlyargs, *a.args, *a.kwonlyargs,
            *([a.vararg] if a.vararg else []), *([a.kwarg] if a.kwarg else [])]
    return [x.annotation for x in args if x.annotation is not None] + \
        ([f.returns] if f.returns is not None else [])


def aliases(modules: list[tuple[str, ast.Module]]) -> frozenset[str]:
    """JSON_MAPS and every module-level alias whose value names one of them (to a fixed
    point: an alias of an alias counts)."""
    return alias_closure(modules, JSON_MAPS, _names_map)


def alias_closure(modules: Iterable[tuple[str, ast.Module]], seeds: Iterable[str],
                  names: Callable[[ast.expr, set[str]], bool]) -> frozenset[str]:
    """`seeds` and every module-level alias (`X = ...`, `X: TypeAlias = ...`) whose value
    `names` one of them, to a fixed point (tests/test_object_annotations.py uses it too)."""
    found = set(seeds)
    defs: list[tuple[str, ast.expr]] = []
    for _, tree in modules:
        for n in tree.body:
            if isinstance(n, ast.Assign) and len(n.targets) == 1 \
                    and isinstance(n.targets[0], ast.Name):
                defs.append((n.targets[0].id, n.value))
            elif isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name) \
                    and n.value is not None and "TypeAlias" in ast.unparse(n.annotation):
                defs.append((n.target.id, n.value))
    changed = True
    while changed:
        changed = False
        for name, value in defs:
            if name not in found and names(value, found):
                found.add(name)
                changed = True
    return frozenset(found)


def _names_map(node: ast.expr, maps: frozenset[str] | set[str]) -> bool:
    """Does the type expression `node` name a JSON map (a whole form or an alias)?"""
    text = ast.unparse(node).replace('"', "").replace("'", "")
    if any(m in text for m in maps if "[" in m):
        return True
    return any(isinstance(n, ast.Name) and n.id in maps
               or isinstance(n, ast.Constant) and n.value in maps
               or isinstance(n, ast.Attribute) and n.attr in maps
               for n in ast.walk(node))


def _module(path: str) -> str:
    return path.removesuffix(".py").removesuffix("/__init__").replace("/", ".")


def _defs(tree: ast.Module) -> Iterator[tuple[str, FunctionNode]]:
    """(qualifier, function) of the module's functions: '' at module level, else 'method'."""
    for n in tree.body:
        if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef):
            yield "", n
        elif isinstance(n, ast.ClassDef):
            for m in n.body:
                if isinstance(m, ast.FunctionDef | ast.AsyncFunctionDef):
                    yield "method", m


class Scope:
    """What a call in one module refers to: its own functions and what it imports."""

    def __init__(self, path: str, tree: ast.Module) -> None:
        self.module = _module(path)
        self.imported: dict[str, tuple[str, str]] = {}    # local name -> (module, name)
        self.modules: dict[str, str] = {}                 # local name -> module
        for n in ast.walk(tree):
            if isinstance(n, ast.ImportFrom) and n.module and not n.level:
                for a in n.names:
                    self.imported[a.asname or a.name] = (n.module, a.name)
            elif isinstance(n, ast.Import):
                for a in n.names:
                    if a.asname:
                        self.modules[a.asname] = a.name

    def target(self, call: ast.AST) -> tuple[str, str] | None:
        """(module, function) a call names, or for `x.f(...)` on no module, (this module,
        'method f'): a method reader is followed within its own module."""
        if not isinstance(call, ast.Call):
            return None
        f = call.func
        if isinstance(f, ast.Name):
            return self.imported.get(f.id, (self.module, f.id))
        if isinstance(f, ast.Attribute):
            if isinstance(f.value, ast.Name) and f.value.id in self.modules:
                return self.modules[f.value.id], f.attr
            if isinstance(f.value, ast.Name) and f.value.id in self.imported:
                mod, name = self.imported[f.value.id]
                return f"{mod}.{name}", f.attr              # `module.function` imported
            return self.module, f"method {f.attr}"
        return None


def readers(modules: list[tuple[str, ast.Module]], maps: frozenset[str]
            ) -> frozenset[tuple[str, str]]:
    """The project's JSON readers, as (module, function) or (module, 'method name'):
    functions returning a JSON map that call json.load(s) or another reader (to a fixed
    point), calls followed through the imports."""
    candidates = [(Scope(path, tree), (Scope(path, tree).module,
                                       f"{kind} {f.name}".strip()), f)
                  for path, tree in modules for kind, f in _defs(tree)
                  if f.returns is not None and _names_map(f.returns, maps | ANY_MAPS)]
    found: set[tuple[str, str]] = set()
    changed = True
    while changed:
        changed = False
        for scope, key, f in candidates:
            if key not in found and any(_is_json_load(n) or scope.target(n) in found
                                        for n in ast.walk(f)):
                found.add(key)
                changed = True
    return frozenset(found)


def count(root: Path = ROOT, dirs: Iterable[str] = SCANNED) -> Counts:
    """Per file under `dirs` outside CODECS: its JSON reads and JSON map signatures (only
    files with one); the aliases and readers are those of all SCANNED layers."""
    modules = list(python_files(root))
    maps = aliases(modules)
    reader_keys = readers(modules, maps)
    prefixes = tuple(f"{d.rstrip('/')}/" for d in dirs)
    out: Counts = {}
    for path, tree in modules:
        if path in CODECS or path in YAML_LOADER or not path.startswith(prefixes):
            continue
        scope = Scope(path, tree)
        c: Counter[str] = Counter()
        for n in ast.walk(tree):
            if _is_json_load(n) or scope.target(n) in reader_keys:
                c["json_reads"] += 1
        for f in _functions(tree):
            if any(_names_map(a, maps) for a in _annotations(f)):
                c["json_map_signatures"] += 1
        if c:
            out[path] = dict(sorted(c.items()))
    return out


def offences(found: Counts, allowed: Counts) -> list[str]:
    """Each file whose count exceeds what `allowed` lists for it (absent: 0)."""
    out = []
    for path, counts in sorted(found.items()):
        for what, n in counts.items():
            limit = allowed.get(path, {}).get(what, 0)
            if n > limit:
                out.append(f"{path}: {what} {n} > {limit} allowed")
    return out


if __name__ == "__main__":
    print("ALLOWED: dict[str, dict[str, int]] = {")
    for p, c in count().items():
        print(f"    \"{p}\": {json.dumps(c)},")
    print("}")
