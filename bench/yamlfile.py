"""YAML files that remember where each key was written.

Every problem the bench reports about an input file names its file, line and key path,
so the loader keeps the line of every mapping key and sequence item it builds.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml


class _Loader(yaml.SafeLoader):
    """YAML 1.1's SafeLoader, but `1e6` and `1.0e6` are numbers (as in YAML 1.2).

    PyYAML reads an exponent without a sign as text, so `impedance_ohm: 1.0e6` would be
    refused as "text"; an engineer writes it that way, so we read it as they mean it.
    """


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                |[-+]?\.(?:inf|Inf|INF)
                |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."))

KeyPath = tuple[str | int, ...]


def keypath_str(path: KeyPath) -> str:
    out = ""
    for part in path:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out or "(top level)"


@dataclass(frozen=True)
class Problem:
    """One thing wrong with an input file: where, which key, what was expected."""

    file: str
    line: int | None
    key: str
    message: str

    def __str__(self) -> str:
        where = f"{self.file}:{self.line}" if self.line else self.file
        return f"{where}: {self.key}: {self.message}"


@dataclass
class YamlDoc:
    """A parsed YAML file with the line (1-based) of every key path."""

    path: Path
    data: Any
    lines: dict[KeyPath, int] = field(default_factory=dict)

    def line(self, path: KeyPath) -> int | None:
        """The line of the key path, or of its nearest written ancestor."""
        while True:
            if path in self.lines:
                return self.lines[path]
            if not path:
                return None
            path = path[:-1]

    def problem(self, path: KeyPath, message: str) -> Problem:
        return Problem(str(self.path), self.line(path), keypath_str(path), message)


class YamlError(Exception):
    """The file cannot be read or parsed at all."""

    def __init__(self, problem: Problem) -> None:
        super().__init__(str(problem))
        self.problem = problem


def _build(node: yaml.Node, path: KeyPath, lines: dict[KeyPath, int],
           loader: yaml.SafeLoader) -> Any:
    lines.setdefault(path, node.start_mark.line + 1)
    if isinstance(node, yaml.MappingNode):
        out: dict[str, Any] = {}
        for key_node, value_node in node.value:
            key = loader.construct_object(key_node, deep=True)
            sub = (*path, key)
            if key in out:
                raise YamlError(Problem("", key_node.start_mark.line + 1, keypath_str(sub),
                                        "duplicate key"))
            lines[sub] = key_node.start_mark.line + 1
            out[key] = _build(value_node, sub, lines, loader)
        return out
    if isinstance(node, yaml.SequenceNode):
        return [_build(item, (*path, i), lines, loader) for i, item in enumerate(node.value)]
    return loader.construct_object(node, deep=True)


def load_yaml(path: str | Path) -> YamlDoc:
    """Parse a YAML file into plain data plus key-path lines; YamlError if unreadable."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise YamlError(Problem(str(p), None, "(file)", "file not found")) from None
    except OSError as e:
        raise YamlError(Problem(str(p), None, "(file)", f"cannot read: {e.strerror}")) from None
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        lines: dict[KeyPath, int] = {}
        data = _build(node, (), lines, loader) if node is not None else None
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        line = mark.line + 1 if mark else None
        msg = f"YAML syntax: {e.problem or e.context}"
        raise YamlError(Problem(str(p), line, "(syntax)", msg)) from None
    except YamlError as e:
        raise YamlError(Problem(str(p), e.problem.line, e.problem.key, e.problem.message)) from None
    finally:
        loader.dispose()
    return YamlDoc(p, data, lines)
