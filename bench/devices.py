"""`bench devices STAND.yaml`: open each instrument, print its identity, close.

The first thing to run on a new bench: it proves every address in the stand file
reaches the instrument it names, before any procedure moves the table.
"""

from __future__ import annotations

import sys

from bench.clock import MonotonicClock
from bench.config import stand_schema
from bench.instruments import Bench, open_axis
from bench.schema import validate
from bench.simbench import SimBench
from bench.yamlfile import YamlError, load_yaml


def list_devices(stand_path: str, sim: bool = False) -> int:
    try:
        doc = load_yaml(stand_path)
    except YamlError as e:
        print(e, file=sys.stderr)
        return 2
    problems = validate(doc, stand_schema())
    if problems:
        for p in problems:
            print(p, file=sys.stderr)
        return 2
    stand = doc.data
    simbench = None
    clock: object = MonotonicClock()
    status = 0
    try:
        if sim or "sim" in stand:
            simbench = SimBench(stand)
            stand = simbench.start()
            clock = simbench.clock
            simbench.start_clock()
        for axis, cfg in stand["axes"].items():
            bench = Bench()
            try:
                ax = open_axis(bench, axis, cfg, clock, None)  # type: ignore[arg-type]
                for what, ident in ax.identities.items():
                    print(f"{axis:<8} {what:<8} {ident}")
                ax.drive.disable()
            except Exception as e:  # noqa: BLE001 - report every instrument
                print(f"{axis:<8} ERROR    {e}", file=sys.stderr)
                status = 3
            finally:
                bench.close()
    finally:
        if simbench is not None:
            simbench.stop()
    return status
