"""`bench devices STAND.yaml`: open each instrument, print its identity, close.

The first thing to run on a new bench: it proves every address in the stand file
reaches the instrument it names, before any procedure moves the table. A stand file
does not say which procedure it serves, so it is checked against each procedure kind's
stand schema and opened by the first kind it fits, through that kind's own code.
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

from bench.core.config import Config
from bench.core.registry import procedure_kind, procedure_names
from bench.core.schema import validate
from bench.core.stops import Stops
from bench.core.yamlfile import Problem, YamlError, load_yaml
from drivers.clock import Clock, MonotonicClock

if TYPE_CHECKING:
    from bench.core.simbench import SimBench


def stand_config(stand_path: str) -> Config | None:
    """A stand file alone as a Config of the first procedure kind whose stand schema it
    fits; None (its problems printed, file, line and key) when it fits none."""
    try:
        doc = load_yaml(stand_path)
    except YamlError as e:
        print(e, file=sys.stderr)
        return None
    fits: list[tuple[list[Problem], str]] = []
    for name in procedure_names():
        fits.append((validate(doc, procedure_kind(name).settings.stand_schema()), name))
    problems, name = min(fits, key=lambda f: len(f[0]))
    if problems:
        for p in problems:
            print(p, file=sys.stderr)
        return None
    return Config(doc.path, doc.path, {"procedure": name}, doc.data, doc, doc)


def list_devices(stand_path: str, sim: bool = False) -> int:
    cfg = stand_config(stand_path)
    if cfg is None:
        return 2
    kind = procedure_kind(cfg.kind)
    stand = cfg.stand_settings
    stops = Stops()    # the twins and instruments register their stops as they open
    status = 0
    simbench: SimBench | None = None
    try:
        with stops.collecting():
            if sim or cfg.has_sim:
                simbench, stand = kind.steps.start_sim(cfg)
            clock: Clock = simbench.clock if simbench is not None else MonotonicClock()
            bench = kind.steps.open_bench(cfg, stand, clock, None)
            if simbench is not None:
                simbench.start_clock()
            for axis, ax in bench.axes.items():
                for what, ident in ax.identities.items():
                    print(f"{axis:<8} {what:<8} {ident}")
    except Exception as e:  # noqa: BLE001 - say which instrument did not answer
        print(f"ERROR: {e}", file=sys.stderr)
        status = 3
    finally:
        stops.run()
    for outcome in stops.failures:   # beneath the first cause, never in its place
        print(f"  also, while stopping: {outcome.text}", file=sys.stderr)
    return 3 if stops.failures else status
