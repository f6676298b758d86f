"""Load a procedure and its stand file: validate, cross-check, then parse (CONTRACT §2).

`load_config` returns a `Config` or raises `ConfigError` carrying every problem found,
each naming file, line and key path. Nothing moves before this has passed.

Everything is reported in one pass: both files' schema problems, the lab file's, and the
cross-checks (axes the stand lacks, rates over its limits) of every part that parsed. A
value the schema refused is left out of the cross-checks, so one mistake is reported
once, where it was written, and hides nothing else.

A placeholder (`TO FILL IN: ...`, bench/core/placeholders.py) is read as its key left
out; `bench validate` lists each as a note.
"""

from __future__ import annotations

import copy
import dataclasses
import os
from functools import reduce
from pathlib import Path
from typing import Any

from bench.core.config import Config, ConfigError, real_stand_problems, struct_problems
from bench.core.lab import lab_problems
from bench.core.placeholders import without_placeholders
from bench.core.registry import procedure_kind, procedure_names
from bench.core.schema import Map, Node, merge, validate
from bench.core.yamlfile import KeyPath, Problem, YamlDoc, YamlError, keypath_str, load_yaml


def any_stand_schema() -> Map:
    """The stand file as some installed procedure kind reads it (the kinds' union): what
    a stand validated alone, or named by an unknown procedure, is checked against."""
    schemas: list[Node] = [procedure_kind(n).settings.stand_schema() for n in procedure_names()]
    node = reduce(merge, schemas)
    assert isinstance(node, Map)
    return node


def is_stand_file(doc: YamlDoc) -> bool:
    """A stand file (`stand:` identity and `axes:`), not a procedure naming one."""
    data = doc.data
    return (isinstance(data, dict) and "procedure" not in data
            and isinstance(data.get("stand"), dict) and "axes" in data)


def _bad_paths(problems: list[Problem], doc: YamlDoc) -> list[KeyPath]:
    """The key paths of `doc` whose values the schema refused."""
    by_text = {keypath_str(path): path for path in doc.lines}
    return [by_text[p.key] for p in problems
            if p.file == str(doc.path) and p.key in by_text and by_text[p.key]
            and not p.message.startswith("missing required key")]


def _without(data: Any, paths: list[KeyPath]) -> Any:
    """A copy of `data` without the values at `paths` (a refused value is not cross-checked)."""
    out = copy.deepcopy(data)
    for path in sorted(paths, key=len, reverse=True):
        parent = out
        for part in path[:-1]:
            try:
                parent = parent[part]
            except (KeyError, IndexError, TypeError):
                parent = None
                break
        if isinstance(parent, dict):
            parent.pop(path[-1], None)
        elif isinstance(parent, list) and isinstance(path[-1], int) \
                and path[-1] < len(parent):
            parent[path[-1]] = None
    return out


def _cross_checks(kind: Any, cfg: Config) -> list[Problem]:
    """The kind's cross-checks; on data with refused parts left out, axis by axis, so
    an axis whose files are too broken to check does not hide the others."""
    try:
        return list(kind.settings.cross_check(cfg))
    except (KeyError, TypeError, ValueError, AttributeError, IndexError, ArithmeticError):
        pass
    axes = cfg.procedure.get("axes")
    out: list[Problem] = []
    if not isinstance(axes, dict):
        return out
    for name, spec in axes.items():
        one = Config(cfg.procedure_path, cfg.stand_path,
                     {**cfg.procedure, "axes": {name: spec}}, cfg.stand,
                     cfg.procedure_doc, cfg.stand_doc)
        try:
            out += [p for p in kind.settings.cross_check(one) if p not in out]
        except (KeyError, TypeError, ValueError, AttributeError, IndexError, ArithmeticError):
            continue
    return out


def _mapping_file(path: str | Path, shape: str) -> YamlDoc:
    """A YAML file whose top level is a mapping, else ConfigError (nothing more to check)."""
    try:
        doc = load_yaml(path)
    except YamlError as e:
        raise ConfigError([e.problem]) from None
    if not isinstance(doc.data, dict):
        raise ConfigError([doc.problem((), f"expected a mapping ({shape})")])
    return doc


def load_stand(stand_path: str | Path) -> YamlDoc:
    """A stand file validated alone (`bench validate STAND.yaml`); ConfigError lists all."""
    written = _mapping_file(stand_path, "stand: ..., axes: ...")
    schema = any_stand_schema()
    sdoc = without_placeholders(written, schema)
    # a placeholder is there to be filled in: the real-stand rules count it as stated
    refused = validate(sdoc, schema)
    problems = refused + struct_problems(sdoc, refused) + real_stand_problems(written)
    if problems:
        raise ConfigError(problems)
    return sdoc


def load_config(procedure_path: str | Path, stand_path: str | Path | None = None) -> Config:
    """Load, validate and cross-check a procedure and its stand; ConfigError lists all."""
    problems: list[Problem] = []
    refused: list[Problem] = []   # the schema's: those values are left out of cross-checks
    pdoc = _mapping_file(procedure_path, "procedure: ..., stand: ...")
    name = pdoc.data.get("procedure")
    kind = procedure_kind(name) if name in procedure_names() else None
    if kind is None:
        problems.append(pdoc.problem(("procedure",), f"expected one of "
                                     f"{', '.join(procedure_names())}, got {name!r}"))
    else:
        pdoc = without_placeholders(pdoc, kind.settings.procedure_schema())
        refused = validate(pdoc, kind.settings.procedure_schema())
        problems += refused
    problems += lab_problems(Path(procedure_path), pdoc, pdoc.data.get("certificate"))
    sdoc: YamlDoc | None = None
    stand_ref = stand_path or pdoc.data.get("stand")
    if isinstance(stand_ref, str | Path):
        spath = Path(stand_ref)
        if stand_path is None and not spath.is_absolute():
            spath = Path(os.path.normpath(Path(procedure_path).parent / spath))
        try:
            written = load_yaml(spath)
        except YamlError as e:
            if e.problem.key == "(file)":
                problems.append(pdoc.problem(("stand",), f"stand file {spath}: "
                                             f"{e.problem.message}"))
            else:
                problems.append(e.problem)
        else:
            schema = kind.settings.stand_schema() if kind is not None else any_stand_schema()
            sdoc = without_placeholders(written, schema)
            stand_refused = validate(sdoc, schema)
            refused += stand_refused
            problems += stand_refused + struct_problems(sdoc, stand_refused)
            problems += real_stand_problems(written)   # as load_stand
    if kind is None or sdoc is None or not isinstance(sdoc.data, dict):
        raise ConfigError(problems)
    if not problems:
        cfg = Config(Path(procedure_path), sdoc.path, pdoc.data, sdoc.data, pdoc, sdoc)
        problems += kind.settings.cross_check(cfg)
        if problems:
            raise ConfigError(problems)
        # parsed once, here: the kind's settings (the stand's parse on first use)
        return dataclasses.replace(cfg, settings=kind.settings.parse(cfg))
    # some parts were refused: cross-check the rest, so one pass reports everything
    stand = _without(sdoc.data, _bad_paths(refused, sdoc))
    procedure = _without(pdoc.data, _bad_paths(refused, pdoc))
    if isinstance(stand.get("axes"), dict) and isinstance(procedure.get("axes"), dict):
        partial = Config(Path(procedure_path), sdoc.path, procedure, stand, pdoc, sdoc)
        problems += [p for p in _cross_checks(kind, partial) if p not in problems]
    raise ConfigError(problems)
