"""Placeholders: values a starter file (`bench init`) leaves for the laboratory to fill in.

A placeholder is a text value starting `TO FILL IN:` followed by what goes there, e.g.
`serial: "TO FILL IN: the counter's serial number"`. The starter writes one wherever only
the laboratory knows the value (serials, calibration certificates, the specification's
source, the mains frequency), so `bench validate` can point at each (a note naming file,
line and key, exit 0) instead of the certificate flagging its absence after a run.

An unfilled placeholder is the key left out, wherever the files are read: the schema
does not type-check it (a due date or a frequency), the run does not use it and the
certificate flags it as it flags an absent key (NOT IDENTIFIED, NOT TRACEABLE): it is
never printed as a value. A block that then lacks a key it requires (a calibration
whose `due` is still to fill in) is left out with it where the block may be left out
(an optional block, a list entry), so half a calibration is no calibration; where the
block may not be left out, validate says what it is missing. The real-stand rules
(bench/core/config.py) count a placeholder as stated: it is there, to be filled in, so
the starter validates; a real stand does not run until none is left (bench run says
so), since only twins may run on values left out.
"""

from __future__ import annotations

import enum
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, TypeGuard

from bench.core import rundir_layout as layout
from bench.core.registry import procedure_kind, procedure_names
from bench.core.schema import Any_, Check, ListOf, Map, MapOf, Node
from bench.core.yamlfile import (
    KeyPath,
    Problem,
    YamlDoc,
    YamlError,
    YamlValue,
    keypath_str,
    load_yaml,
    read_mapping,
)

__all__ = ["PREFIX", "ReadDoc", "is_placeholder", "left_to_fill", "placeholder_notes",
           "placeholders", "run_copy", "without_placeholders"]

#: how every placeholder starts (any case), followed by what goes there
PREFIX = "TO FILL IN:"
_PLACEHOLDER = re.compile(r"\s*" + re.escape(PREFIX), re.IGNORECASE)

class _Absent(enum.Enum):
    """A value left out (None is a value: `key: ~`)."""

    ABSENT = enum.auto()


_ABSENT: Literal[_Absent.ABSENT] = _Absent.ABSENT


def is_placeholder(value: YamlValue) -> TypeGuard[str]:
    """Whether a YAML value is a placeholder: the one test, so nothing reads one as data."""
    return isinstance(value, str) and _PLACEHOLDER.match(value) is not None


def what_goes_there(value: str) -> str:
    """The placeholder's text after its prefix: what the laboratory is to write."""
    return value.strip()[len(PREFIX):].strip()


def placeholders(data: YamlValue, path: KeyPath = ()) -> Iterator[tuple[KeyPath, str]]:
    """Every placeholder in a file's data: its key path and what goes there, in file order."""
    if is_placeholder(data):
        yield path, what_goes_there(data)
    elif isinstance(data, dict):
        for key, value in data.items():
            yield from placeholders(value, (*path, key))
    elif isinstance(data, list):
        for i, value in enumerate(data):
            yield from placeholders(value, (*path, i))


def _strip(value: YamlValue, node: Node, optional: bool, old: KeyPath, new: KeyPath,
           renamed: dict[KeyPath, KeyPath]) -> YamlValue | _Absent:
    """`value` without its placeholders, or _ABSENT. A list entry left out moves those
    after it: `renamed` keeps where each moved one was written (new path -> old path)."""
    if is_placeholder(value):
        return _ABSENT
    while isinstance(node, Check):
        node = node.inner
    if isinstance(value, dict):
        out: dict[str, YamlValue] = {}
        for key, v in value.items():
            child, may_go = _child(node, key)
            if child is None:   # an unknown key: kept whole, for the schema to refuse
                out[key] = v
                continue
            keep = _strip(v, child, may_go, (*old, key), (*new, key), renamed)
            if keep is not _ABSENT:
                out[key] = keep
        if optional and isinstance(node, Map) and any(
                spec.required and key in value and key not in out
                for key, spec in node.keys.items()):
            return _ABSENT
        return out
    if isinstance(value, list):
        item = node.item if isinstance(node, ListOf) else Any_()
        kept: list[YamlValue] = []
        for i, v in enumerate(value):
            at = (*new, len(kept))
            keep = _strip(v, item, True, (*old, i), at, renamed)
            if keep is not _ABSENT:
                if len(kept) != i:
                    renamed[at] = (*old, i)
                kept.append(keep)
        return kept
    return value


def _child(node: Node, key: str) -> tuple[Node | None, bool]:
    """The schema of a mapping's value at `key` (None: a key the schema does not know)
    and whether that value may be left out."""
    if isinstance(node, Map):
        spec = node.keys.get(key)
        return (spec.node, not spec.required) if spec is not None else (None, True)
    if isinstance(node, MapOf):
        return node.value, False     # a name the file chose (an axis): never dropped
    return Any_(), True


@dataclass
class ReadDoc(YamlDoc):
    """A file as the bench reads it (placeholders left out) that still reports each
    problem at the line and key path where it was written."""

    renamed: dict[KeyPath, KeyPath] = field(default_factory=dict)

    def written(self, path: KeyPath) -> KeyPath:
        """Where the value at `path` of the data as read was written in the file."""
        for n in range(len(path), 0, -1):
            if path[:n] in self.renamed:
                return (*self.renamed[path[:n]], *path[n:])
        return path

    def line(self, path: KeyPath) -> int | None:
        return YamlDoc.line(self, self.written(path))

    def problem(self, path: KeyPath, message: str) -> Problem:
        at = self.written(path)
        return Problem(str(self.path), YamlDoc.line(self, at), keypath_str(at), message)


def without_placeholders(doc: YamlDoc, schema: Node) -> ReadDoc:
    """The file as the bench reads it: its placeholders (and the blocks that need them)
    left out. The top level is never left out."""
    renamed: dict[KeyPath, KeyPath] = {}
    data = _strip(doc.data, schema, False, (), (), renamed)
    return ReadDoc(doc.path, data, doc.lines, renamed)


def left_to_fill(*paths: str | Path) -> list[str]:
    """Every placeholder of these files as `file:line: key: to fill in: what`, the form
    of validate's problems, in file order."""
    out = []
    for path in paths:
        try:
            doc = load_yaml(path)
        except YamlError:
            continue    # the loader reports an unreadable file
        out += [str(doc.problem(where, f"to fill in: {what}"))
                for where, what in placeholders(doc.data)]
    return out


def placeholder_notes(*paths: str | Path) -> list[str]:
    """`bench validate`'s notes: what is left to fill in, and what that means meanwhile."""
    left = left_to_fill(*paths)
    if not left:
        return []
    return [*left, f"{len(left)} key(s) to fill in: until then each counts as left out "
            "(twins run without it and the certificate flags it; a real stand does not "
            "run)"]


def run_copy(run_path: str | Path, name: str) -> dict[str, Any]:
    """A run directory's copy of its stand or procedure file as the run read it: its
    placeholders left out (read_mapping's {} when the file is missing or damaged), for
    the readers of run directories (certificate, records)."""
    run = Path(run_path)
    data = read_mapping(run / name)
    kind = read_mapping(run / layout.PROCEDURE).get("procedure")
    if kind in procedure_names():
        schema: Node = (procedure_kind(kind).settings.procedure_schema() if name == layout.PROCEDURE
                        else procedure_kind(kind).settings.stand_schema())
    else:
        schema = Any_()
    got = without_placeholders(YamlDoc(run / name, data), schema).data
    return got if isinstance(got, dict) else {}
