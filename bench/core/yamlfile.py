"""YAML files that remember where each key was written.

Every problem the bench reports about an input file names its file, line and key path,
so the loader keeps the line of every mapping key and sequence item it builds.
"""

from __future__ import annotations

import copy
import datetime as dt
import functools
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeAlias

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

#: a value as the safe loader builds it (a mapping's keys are text in every file we read)
YamlValue: TypeAlias = (str | int | float | bool | dt.date | None | Sequence["YamlValue"]
                        | Mapping[str, "YamlValue"])
#: keys and list indexes from the top; a YAML key may also be a float or null (`1.5:`, `~:`)
KeyPath = tuple[str | int | float | None, ...]


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


#: deeper than this is not a bench file (and would exhaust Python's stack)
MAX_DEPTH = 64
#: values built from one file; aliases can multiply a small file into millions
MAX_VALUES = 200_000


class _Builder:
    """Plain data from a node tree, refusing what no bench file needs and what would
    crash the loader: recursive aliases, deep nesting, alias bombs, lists as keys."""

    def __init__(self, loader: yaml.SafeLoader) -> None:
        self.loader = loader
        self.lines: dict[KeyPath, int] = {}
        self.count = 0
        self._open: set[int] = set()  # ids of the collections being built (alias loops)

    def _refuse(self, node: yaml.Node, path: KeyPath, message: str) -> YamlError:
        return YamlError(Problem("", node.start_mark.line + 1, keypath_str(path), message))

    def _scalar(self, node: yaml.Node, path: KeyPath) -> object:
        try:
            return self.loader.construct_object(node, deep=True)
        except yaml.MarkedYAMLError as e:
            raise self._refuse(node, path, f"YAML: {e.problem or e.context}") from None
        except (ValueError, TypeError, OverflowError) as e:  # e.g. a date 2024-13-45
            raise self._refuse(node, path, f"cannot read the value {node.value!r}: "
                                           f"{e}") from None

    def build(self, node: yaml.Node, path: KeyPath = ()) -> object:
        self.lines.setdefault(path, node.start_mark.line + 1)
        self.count += 1
        if self.count > MAX_VALUES:
            raise self._refuse(node, path, f"more than {MAX_VALUES} values (aliases "
                                           "repeating a large block?)")
        if len(path) > MAX_DEPTH:
            raise self._refuse(node, path[:8], f"nested deeper than {MAX_DEPTH} levels")
        if not isinstance(node, yaml.MappingNode | yaml.SequenceNode):
            return self._scalar(node, path)
        if id(node) in self._open:
            raise self._refuse(node, path, "an alias refers to a collection it is inside "
                                           "(a recursive alias)")
        self._open.add(id(node))
        try:
            if isinstance(node, yaml.SequenceNode):
                return [self.build(item, (*path, i)) for i, item in enumerate(node.value)]
            out: dict[str | int | float | bool | None, object] = {}
            for key_node, value_node in node.value:
                if not isinstance(key_node, yaml.ScalarNode):
                    kind = "a list" if isinstance(key_node, yaml.SequenceNode) else "a mapping"
                    raise self._refuse(key_node, (*path, "?"),
                                       f"a key must be a name, not {kind}")
                if key_node.tag == "tag:yaml.org,2002:merge":
                    raise self._refuse(key_node, (*path, "<<"), "merge keys (<<) are not "
                                                                "supported; write the keys")
                key = self._scalar(key_node, (*path, "?"))
                if not isinstance(key, str | int | float | bool) and key is not None:
                    raise self._refuse(key_node, (*path, "?"),
                                       f"a key must be a name, not {type(key).__name__}")
                sub = (*path, key)
                if key in out:
                    raise self._refuse(key_node, sub, "duplicate key")
                self.lines[sub] = key_node.start_mark.line + 1
                out[key] = self.build(value_node, sub)
            return out
        finally:
            self._open.discard(id(node))


@dataclass(slots=True)
class _Frame:
    """A collection open where `_syntax_path`'s scan stands."""

    path: KeyPath
    is_map: bool
    line: int | None                 # where it was opened
    expecting_key: bool = True       # a mapping's next scalar is a key
    key: str | int = 0               # a mapping's last key, a list's next index


def _syntax_path(text: str) -> tuple[KeyPath, int | None]:
    """The key path of the innermost collection open where the parser gave up, and the
    line it was opened on: "rates_dps: [10, 20" unclosed is reported at rates_dps, not
    at the next line where the parser noticed."""
    frames: list[_Frame] = []

    def child_path() -> KeyPath:
        if not frames:
            return ()
        f = frames[-1]
        return (*f.path, "?") if f.is_map and f.expecting_key else (*f.path, f.key)

    def advance() -> None:
        if frames:
            f = frames[-1]
            if f.is_map:
                f.expecting_key = not f.expecting_key
            elif isinstance(f.key, int):
                f.key += 1

    try:
        for ev in yaml.parse(text, Loader=_Loader):
            if isinstance(ev, yaml.MappingStartEvent | yaml.SequenceStartEvent):
                frames.append(_Frame(child_path(), isinstance(ev, yaml.MappingStartEvent),
                                     ev.start_mark.line + 1 if ev.start_mark else None))
            elif isinstance(ev, yaml.MappingEndEvent | yaml.SequenceEndEvent):
                frames.pop()
                advance()
            elif isinstance(ev, yaml.ScalarEvent | yaml.AliasEvent):
                if frames and frames[-1].is_map and frames[-1].expecting_key:
                    frames[-1].key = getattr(ev, "value", "?")
                advance()
    except (yaml.YAMLError, RecursionError):
        pass
    if not frames:
        return (), None
    return frames[-1].path, frames[-1].line


#: PyYAML's phrases and what they mean in a bench file
_PLAIN = (
    ("found character '\\t'", "a tab character{at}: YAML indents with spaces only; "
                               "replace the tab with spaces"),
    ("mapping values are not allowed", "a colon where a value was expected{at}: indent "
                                       "the key under its parent, or quote a value "
                                       "containing ': '"),
    ("could not find expected ':'", "a line without 'key: value'{at}: add the colon, or "
                                    "indent it under the key it continues"),
    ("expected <block end>", "the indentation does not match the lines above{at}: keys "
                             "of one mapping start in the same column"),
    ("found undefined alias", "an alias (*name) with no anchor (&name) before it{at}"),
)


def _plain_sentence(problem: str, text: str, line: int | None) -> str | None:
    """PyYAML's message as a plain sentence, naming the key written on that line."""
    for phrase, sentence in _PLAIN:
        if phrase in problem:
            at = ""
            if line is not None:
                # PyYAML counts "\n" breaks; splitlines() also splits on \x0b, \x1c...
                lines = text.split("\n")
                src = lines[line - 1] if 0 < line <= len(lines) else ""
                m = re.match(r"\s*-?\s*([\w.+-]+)\s*:", src)
                at = f" on the line of {m.group(1)!r}" if m else f" on line {line}"
            return sentence.format(at=at)
    return None


def _line_of_offset(text: str, offset: int) -> int:
    return text.count("\n", 0, max(offset, 0)) + 1


def load_yaml(path: str | Path) -> YamlDoc:
    """Parse a YAML file into plain data plus key-path lines; YamlError if unreadable.

    Never raises anything else, whatever the bytes: `bench validate` answers every file
    with its problems (file, line, key), not a traceback.
    """
    p = Path(path)
    try:
        raw = p.read_bytes()
    except FileNotFoundError:
        raise YamlError(Problem(str(p), None, "(file)", "file not found")) from None
    except (OSError, ValueError) as e:
        why = e.strerror if isinstance(e, OSError) and e.strerror else str(e)
        raise YamlError(Problem(str(p), None, "(file)", f"cannot read: {why}")) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        line: int | None = raw.count(b"\n", 0, e.start) + 1
        raise YamlError(Problem(str(p), line, "(file)", f"not UTF-8 text: byte "
                                f"0x{raw[e.start]:02x} at offset {e.start}")) from None
    try:
        data, lines = _parsed(text)
    except yaml.reader.ReaderError as e:
        char = f"U+{e.character:04X}" if isinstance(e.character, int) else repr(e.character)
        raise YamlError(Problem(str(p), _line_of_offset(text, e.position), "(file)",
                                f"control character {char} is not allowed in YAML "
                                f"(offset {e.position})")) from None
    except yaml.MarkedYAMLError as e:
        where, opened = _syntax_path(text)
        noticed = e.problem_mark.line + 1 if e.problem_mark else None
        line = opened if opened is not None and "flow" in (e.context or "") else noticed
        msg = f"YAML syntax: {e.problem or e.context}"
        plain = _plain_sentence(str(e.problem or e.context), text, noticed)
        if plain:
            msg = f"{plain} (YAML: {e.problem or e.context})"
        elif e.context and e.problem:
            msg += f" ({e.context}"
            msg += f" opened at line {e.context_mark.line + 1})" if e.context_mark else ")"
        if noticed is not None and noticed != line:
            msg += f"; noticed at line {noticed}"
        key = keypath_str(where) if where else "(syntax)"
        raise YamlError(Problem(str(p), line, key, msg)) from None
    except yaml.YAMLError as e:
        raise YamlError(Problem(str(p), None, "(syntax)", f"YAML: {e}")) from None
    except _TooDeep as e:
        raise YamlError(Problem(str(p), e.line + 1 if isinstance(e.line, int) else None,
                                "(syntax)", f"nested too deeply (more than {MAX_DEPTH} "
                                "levels)")) from None
    except YamlError as e:
        raise YamlError(Problem(str(p), e.problem.line, e.problem.key, e.problem.message)) from None
    # a copy: the parse is kept for the next reader of the same text, who gets it as written
    return YamlDoc(p, copy.deepcopy(data), dict(lines))


class _TooDeep(Exception):
    """The parser ran out of stack; `line`: where it was (0-based), if it knew."""

    def __init__(self, line: int | None) -> None:
        super().__init__(line)
        self.line = line


#: texts longer than this are parsed each time they are read, not kept
PARSED_KEPT_MAX_CHARS = 1 << 18


def _parsed(text: str) -> tuple[object, dict[KeyPath, int]]:
    """The data of a YAML text and the line of every key path (the parser's errors
    raised as they are). The last few texts' parses are kept, by their text: `bench
    validate` reads a procedure file three times and its stand file twice, and PyYAML
    takes tens of milliseconds a file."""
    if len(text) > PARSED_KEPT_MAX_CHARS:
        return _parse(text)
    return _parse_kept(text)


def _parse(text: str) -> tuple[object, dict[KeyPath, int]]:
    loader: _Loader | None = None
    try:
        loader = _Loader(text)
        node = loader.get_single_node()
        builder = _Builder(loader)
        data = builder.build(node) if node is not None else None
        return data, builder.lines or {(): 1}  # an empty file: its problems are on line 1
    except RecursionError:
        raise _TooDeep(getattr(loader, "line", None)) from None
    finally:
        if loader is not None:
            loader.dispose()


_parse_kept = functools.lru_cache(maxsize=16)(_parse)


def read_mapping(path: str | Path) -> dict[str, Any]:
    """A YAML file's top-level mapping through the one reader (its number fix included),
    or {} when the file is missing, damaged or not a mapping: for readers of run
    directories they did not write (certificate, station), which show what they can."""
    try:
        data = load_yaml(path).data
    except YamlError:
        return {}
    return data if isinstance(data, dict) else {}
