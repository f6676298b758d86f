"""The configuration reference, generated from the one schema (`bench schema`).

Every key of the stand, procedure and lab files, with its type, unit, default, meaning
and whether it must be written, comes from the schema nodes the validator checks with
(bench/core/config.py, bench/core/lab.py, each procedure kind's settings): the reference, the JSON
Schema and docs/configuration.md cannot drift from what `bench validate` accepts.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass

from bench.core.lab import LAB
from bench.core.loader import any_stand_schema
from bench.core.registry import procedure_kind, procedure_names
from bench.core.schema import Check, Key, ListOf, Map, MapOf, Node, Num, OneOf

JSON_SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"
DOCS_PATH = "docs/configuration.md"


def stand_node() -> Map:
    """The stand file as every installed procedure kind reads it (their union)."""
    return _note_kind_only(any_stand_schema())


def _note_kind_only(node: Map) -> Map:
    """Say which kind requires a top-level key that the union leaves optional."""
    keys = dict(node.keys)
    for name in procedure_names():
        for k, spec in procedure_kind(name).settings.stand_schema().keys.items():
            if spec.required and not keys[k].required:
                old = keys[k]
                doc = f"required by procedure {name}" + (f"; {old.doc}" if old.doc else "")
                keys[k] = Key(old.node, False, doc, old.default)
    return Map(keys)


def schema_node(target: str, kind: str | None = None) -> Map:
    """The schema of `stand`, `procedure` (of `kind`) or `lab`; KeyError names the choices."""
    if target == "stand":
        return procedure_kind(kind).settings.stand_schema() if kind else stand_node()
    if target == "procedure":
        if kind not in procedure_names():
            raise KeyError(f"procedure KIND: expected one of {', '.join(procedure_names())}"
                           f", got {kind!r}")
        return procedure_kind(kind).settings.procedure_schema()
    if target == "lab":
        return LAB
    raise KeyError(f"expected stand, procedure KIND or lab, got {target!r}")


def json_schema(target: str, kind: str | None = None) -> str:
    """The file's JSON Schema (draft 2020-12) as printed: what a YAML editor or CI can
    check with."""
    title = {"stand": "ratebench stand file", "lab": "ratebench laboratory settings",
             "procedure": f"ratebench {kind} procedure file"}[target]
    return json.dumps({"$schema": JSON_SCHEMA_DIALECT, "title": title,
                       **schema_node(target, kind).json_schema()}, indent=2)


@dataclass(frozen=True)
class Row:
    """One key of the reference."""

    path: str
    type: str
    unit: str
    default: str
    required: bool
    meaning: str


def _type_text(node: Node) -> str:
    if isinstance(node, Check):
        return _type_text(node.inner)
    if isinstance(node, Map):
        return "mapping"
    if isinstance(node, MapOf):
        return f"mapping of names to {_type_text(node.value)}"
    if isinstance(node, ListOf):
        return f"list of {_type_text(node.item)}"
    if isinstance(node, Num):
        return Num(node.min, node.max, node.exclusive_min, node.integer).description
    if isinstance(node, OneOf):
        return " or ".join(_type_text(o) for o in node.options)
    return node.description


def _children(node: Node, path: str) -> list[tuple[Map, str]]:
    """The mappings inside `node` whose keys the reference lists, with their paths."""
    if isinstance(node, Check):
        return _children(node.inner, path)
    if isinstance(node, Map):
        return [(node, path)]
    if isinstance(node, MapOf):
        return _children(node.value, f"{path}.<name>")
    if isinstance(node, ListOf):
        return _children(node.item, f"{path}[]")
    return []


def rows(node: Map, prefix: str = "") -> list[Row]:
    """Every key under `node`, depth first, in the schema's order."""
    out: list[Row] = []
    for k, spec in node.keys.items():
        path = f"{prefix}.{k}" if prefix else k
        default = "" if spec.default is None else json.dumps(spec.default)
        out.append(Row(path, _type_text(spec.node), spec.node.unit_text, default,
                       spec.required, spec.doc))
        for child, child_path in _children(spec.node, path):
            out += rows(child, child_path)
    return out


def text_reference(node: Map) -> str:
    """The reference as plain text for a terminal."""
    out = []
    for r in rows(node):
        head = r.path + ("  (required)" if r.required else "")
        bits = [r.type] + ([f"unit {r.unit}"] if r.unit else []) + (
            [f"default {r.default}"] if r.default else [])
        out.append(head)
        out.append(f"    {'; '.join(bits)}")
        if r.meaning:
            out.append(f"    {r.meaning}")
    return "\n".join(out)


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def markdown_table(node: Map) -> str:
    lines = ["| key | type | unit | default | required | meaning |",
             "| --- | --- | --- | --- | --- | --- |"]
    for r in rows(node):
        lines.append(f"| `{r.path}` | {_cell(r.type)} | {_cell(r.unit)} | "
                     f"{_cell(r.default) and f'`{_cell(r.default)}`'} | "
                     f"{'yes' if r.required else ''} | {_cell(r.meaning)} |")
    return "\n".join(lines)


INTRO = """\
# Configuration reference

<!-- generated by `bench schema --markdown`; edit the schema (bench/core/config.py,
bench/core/lab.py, procedures/*/settings), not this file. A test keeps it current. -->

A run reads three YAML files: a **procedure** (what to measure, `bench run PROCEDURE.yaml`),
the **stand** it names with `stand:` (the instruments and their limits), and optionally the
**laboratory** settings its `certificate: {lab: ...}` names (who issues the certificate).
`bench init DIR` writes commented starting points of all three; `bench validate FILE`
checks a procedure with its stand, or a stand file alone, and reports every problem at once
with file, line and key path.

The same reference is printed by `bench schema stand`, `bench schema procedure KIND` and
`bench schema lab`; `--json` gives each as a JSON Schema (draft 2020-12) for an editor or a
CI check. Units are in the names (`_dps` deg/s, `_s` seconds, `_rel` a plain fraction:
1e-6 is 1 ppm). Keys not listed are refused: a misspelt key never falls back to a default.
`<name>` is a name you choose (an axis, a gyro); `[]` is an item of a list.
"""


def configuration_markdown() -> str:
    """docs/configuration.md, whole."""
    parts = [INTRO, "## Stand file", "",
             "One file per bench. A stand with a `sim:` block runs on the twins; without "
             "one it is a real bench, which must also state what no driver can guess "
             "(`drive.unit_factors`, `counter.level_v`, `counter.reference`, "
             "`counter.time_tie`).", "", markdown_table(stand_node()), ""]
    for name in procedure_names():
        parts += [f"## Procedure file: `procedure: {name}`", "",
                  markdown_table(schema_node("procedure", name)), ""]
    parts += ["## Laboratory file", "",
              "Named by a procedure's `certificate: {lab: ../lab.yaml}`; the procedure's own "
              "`certificate:` keys override it.", "", markdown_table(LAB), ""]
    return "\n".join(parts)


def schema_command(target: str, kind: str | None, as_json: bool, markdown: bool) -> int:
    """`bench schema`: the reference of one file (exit 2 for an unknown target or kind)."""
    if markdown:
        print(configuration_markdown(), end="")
        return 0
    if target == "procedure" and kind is None:
        print(f"bench schema procedure KIND: KIND is one of {', '.join(procedure_names())}",
              file=sys.stderr)
        return 2
    try:
        node = schema_node(target, kind)
    except KeyError as e:
        print(f"bench schema: {e.args[0]}", file=sys.stderr)
        return 2
    if as_json:
        print(json_schema(target, kind))
    else:
        print(text_reference(node))
    return 0


def method_command(path_only: bool) -> int:
    """`bench method`: the method text an installed package ships, so `bench --help` can
    point at it (a wheel carries no docs/ folder)."""
    from importlib.resources import as_file, files

    with as_file(files("bench") / "method.md") as path:
        if path_only:
            print(path)
        else:
            sys.stdout.write(path.read_text(encoding="utf-8"))
    return 0
