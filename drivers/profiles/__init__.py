"""The instruments' profile files, shipped as package data and read through
importlib.resources: the drive's object dictionary (bench-drive.eds, which the driver
and the drive twin both load) and the pyvisa-sim description of the counters
(counters-sim.yaml, a static instrument stand-in for `visa_library="...@sim"`)."""

from __future__ import annotations

import atexit
import contextlib
from importlib import resources
from pathlib import Path

EDS_NAME = "bench-drive.eds"
PYVISA_SIM_COUNTERS = "counters-sim.yaml"

_extracted = contextlib.ExitStack()
atexit.register(_extracted.close)


def profile_path(name: str) -> Path:
    """A real file path for one profile file (canopen and pyvisa-sim open paths; from a
    zipped install the file is extracted once, for the life of the process)."""
    return _extracted.enter_context(resources.as_file(resources.files(__name__) / name))
