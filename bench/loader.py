"""Load a procedure and its stand file: validate, cross-check, then parse (CONTRACT §2).

`load_config` returns a `Config` or raises `ConfigError` carrying every problem found,
each naming file, line and key path. Nothing moves before this has passed.
"""

from __future__ import annotations

import os
from pathlib import Path

from bench.config import Config, ConfigError, real_stand_problems
from bench.lab import lab_problems
from bench.registry import procedure_kind, procedure_names
from bench.schema import validate
from bench.yamlfile import Problem, YamlDoc, YamlError, load_yaml


def load_config(procedure_path: str | Path, stand_path: str | Path | None = None) -> Config:
    """Load, validate and cross-check a procedure and its stand; ConfigError lists all."""
    problems: list[Problem] = []
    try:
        pdoc = load_yaml(procedure_path)
    except YamlError as e:
        raise ConfigError([e.problem]) from None
    if not isinstance(pdoc.data, dict):
        raise ConfigError([pdoc.problem((), "expected a mapping (procedure: ..., stand: ...)")])
    name = pdoc.data.get("procedure")
    if name not in procedure_names():
        raise ConfigError([pdoc.problem(("procedure",), f"expected one of "
                                        f"{', '.join(procedure_names())}, got {name!r}")])
    kind = procedure_kind(name)
    problems += validate(pdoc, kind.procedure_schema())
    problems += lab_problems(Path(procedure_path), pdoc, pdoc.data.get("certificate"))
    sdoc: YamlDoc | None = None
    stand_ref = stand_path or pdoc.data.get("stand")
    if isinstance(stand_ref, str | Path):
        spath = Path(stand_ref)
        if stand_path is None and not spath.is_absolute():
            spath = Path(os.path.normpath(Path(procedure_path).parent / spath))
        try:
            sdoc = load_yaml(spath)
        except YamlError as e:
            if e.problem.key == "(file)":
                problems.append(pdoc.problem(("stand",), f"stand file {spath}: "
                                             f"{e.problem.message}"))
            else:
                problems.append(e.problem)
        else:
            problems += validate(sdoc, kind.stand_schema())
            if not problems:
                problems += real_stand_problems(sdoc)
    if problems or sdoc is None:
        raise ConfigError(problems)
    cfg = Config(Path(procedure_path), sdoc.path, pdoc.data, sdoc.data, pdoc, sdoc)
    problems += kind.cross_check(cfg)
    if problems:
        raise ConfigError(problems)
    return cfg
