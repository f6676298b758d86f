"""Which lab settings the DCC uses, and where the signing key may live.

The settings themselves are the one lab model (bench.core.lab.Lab). The run resolved them when
it started (result.json's `certificate` block, and the lab file copied into the run
directory); a lab file named later (`--lab FILE`, the stand file's `dcc: {lab: FILE}`, or
the environment variable BENCH_LAB_SETTINGS) is read on top of it, and the signing key and
certificate may also be named directly in the stand file (`dcc: {signing: {key: ...,
certificate: ...}}`). Only paths are ever written in those files: a private key's bytes
never enter a run directory (the stand file is copied there), and a key file inside the
run directory is refused.
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

from bench.core.config import STAND_DCC, DccRefs, dcc_refs
from bench.core.lab import LAB, Lab, LabError, Signing, load_lab

__all__ = ["ENV_LAB", "LAB_FILE", "STAND_DCC", "LabSettings", "SettingsError", "Signing",
           "check_key_outside", "load_lab_file", "resolve_settings"]

ENV_LAB = "BENCH_LAB_SETTINGS"
LAB_FILE = LAB                 # the schema: one for every reader of the lab file
LabSettings = Lab              # the one model
SettingsError = LabError
load_lab_file = load_lab


def resolve_settings(stand: DccRefs | None,
                     lab_file: str | Path | None = None,
                     stand_origin: str = "stand file", base: Lab | None = None) -> Lab:
    """The lab settings in force: `--lab` first, then the stand's `dcc.lab`, then the
    environment's BENCH_LAB_SETTINGS, else `base` (the run's own); the stand's own
    `dcc.signing` overrides the key. `stand`: the stand's DCC references (`dcc_refs` of
    a run directory's stand file as read back)."""
    refs = stand if stand is not None else dcc_refs(None)
    chosen = lab_file or refs.lab or os.environ.get(ENV_LAB)
    settings = load_lab(os.path.expanduser(str(chosen))) if chosen else (base or Lab())
    if not (refs.signing_key and refs.signing_certificate):
        return settings
    stand_signing = Signing(Path(os.path.expanduser(refs.signing_key)),
                            Path(os.path.expanduser(refs.signing_certificate)),
                            refs.password_env, f"{stand_origin}: dcc.signing")
    return replace(settings, signing=stand_signing, require_signed_dcc=True)


def check_key_outside(signing: Signing, run_path: Path) -> None:
    """Refuse a key kept inside the run directory: it would travel with the evidence."""
    key = signing.key_file.resolve()
    if key.is_relative_to(run_path.resolve()):
        raise SettingsError(f"{signing.origin}: the private key {key} lies inside the run "
                            f"directory {run_path}; keep it outside (the run directory is "
                            "handed on with the certificate)")
