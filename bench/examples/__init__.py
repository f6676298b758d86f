"""The example procedures shipped inside the package (`bench run --example NAME`).

They are package data read through importlib.resources, so an installed wheel runs the
demo with no checkout. In the source tree each file here is a link to the same file in
configs/ (one copy; the wheel holds the file itself).
"""

from __future__ import annotations

import atexit
import contextlib
from importlib import resources
from pathlib import Path

_extracted = contextlib.ExitStack()
atexit.register(_extracted.close)


def example_names() -> list[str]:
    """The shipped procedures' names: `demo`, `drift-demo`."""
    return sorted(p.name.removesuffix(".yaml")
                  for p in (resources.files(__name__) / "procedures").iterdir()
                  if p.name.endswith(".yaml"))


def example_path(name: str) -> Path:
    """A real path to the shipped procedure `name` (its stand file beside it, as its
    `stand:` key says); KeyError naming the choices when there is none."""
    if name not in example_names():
        raise KeyError(f"no example procedure {name!r}; the package ships "
                       f"{', '.join(example_names())}")
    root = _extracted.enter_context(resources.as_file(resources.files(__name__)))
    return Path(root) / "procedures" / f"{name}.yaml"
