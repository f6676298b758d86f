"""`bench init [DIR] [--real] [--kind KIND]`: commented stand, procedure and lab files to
start from.

A new lab starts from files that validate and say what each key means, rather than
from copies of configs/ learned key by key from the validator. The stand and procedure
files are the procedure kind's (`bench.kind.HasStarterFiles`; by default the first
installed kind that offers them); the lab file is the same for every kind. Without
--real the stand runs on the twins (a `sim:` block), so `bench run DIR/procedure.yaml
--yes` works at once; --real leaves out `sim:` and writes the keys a real bench must state.

What only the laboratory knows (serials, calibrations, the specification's source) is
written as a placeholder, `"TO FILL IN: ..."` (bench/core/placeholders.py): the files
validate and the twins run at once, `bench validate` lists each placeholder by file,
line and key, and the certificate flags each left unfilled instead of printing it.
"""

from __future__ import annotations

import sys
from pathlib import Path

from bench.core.config import ConfigError
from bench.core.loader import load_config
from bench.core.placeholders import left_to_fill
from bench.core.registry import procedure_names
from bench.kind import HasStarterFiles, installed_records

EXIT_OK, EXIT_INVALID = 0, 2

LAB = """\
# The laboratory's settings (docs/configuration.md, `bench schema lab`): printed on every
# certificate it issues. Procedures name it with `certificate: {lab: lab.yaml}`.
laboratory: Example Rate Table Laboratory
address: 1 Example Street, Example City
accreditation: not accredited        # or the body and number
prefix: RT                           # certificate numbers RT-...
signatories:                         # who signs; one of them authorises the issue
  - {name: A. Engineer, function: Calibration engineer}
  - {name: B. Manager, function: Technical manager, authorises: true}
"""


def starter_kind(name: str | None) -> HasStarterFiles | None:
    """The kind named, or the first installed one that offers starter files."""
    for n in [name] if name else procedure_names():
        kind = installed_records(n)
        if isinstance(kind, HasStarterFiles):
            return kind
    return None


def starter_files(real: bool, kind: str | None = None) -> dict[str, str]:
    """File name -> text of the three starter files ({} when no kind offers them)."""
    maker = starter_kind(kind)
    return {**maker.starter_files(real), "lab.yaml": LAB} if maker is not None else {}


def init_command(folder: str, real: bool, kind: str | None = None) -> int:
    """Write the starter files into `folder`; never overwrite one (exit 2)."""
    where = Path(folder)
    files = starter_files(real, kind)
    if not files:
        offer = [n for n in procedure_names() if starter_kind(n) is not None]
        print(f"bench init: {'procedure kind ' + repr(kind) if kind else 'no kind'} offers "
              f"no starter files; kinds that do: {', '.join(offer) or 'none installed'}",
              file=sys.stderr)
        return EXIT_INVALID
    existing = [where / n for n in files if (where / n).exists()]
    if existing:
        print(f"bench init: not overwriting {', '.join(map(str, existing))}; choose "
              "another folder", file=sys.stderr)
        return EXIT_INVALID
    where.mkdir(parents=True, exist_ok=True)
    for name, text in files.items():
        (where / name).write_text(text, encoding="utf-8")
    try:
        load_config(where / "procedure.yaml")
    except ConfigError as e:  # a bug in the templates: say so rather than leave it
        print(f"bench init: the starter files do not validate (a bug):\n{e}",
              file=sys.stderr)
        return EXIT_INVALID
    proc = where / "procedure.yaml"
    print(f"wrote {where / 'stand.yaml'}, {proc}, {where / 'lab.yaml'}")
    left = len(left_to_fill(proc, where / "stand.yaml"))
    if left:
        print(f"{left} values are yours to fill in (TO FILL IN: ...; bench validate lists "
              "each by file, line and key); "
              + ("a real stand runs once none is left" if real else
                 "the twins run meanwhile, the certificate flagging each"))
    print(f"next: bench validate {proc}; bench plan {proc}; "
          + (f"bench devices {where / 'stand.yaml'}" if real else f"bench run {proc} --yes"))
    return EXIT_OK
