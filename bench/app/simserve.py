"""`bench sim STAND.yaml`: the stand's twins alone, for scripts written elsewhere.

A user develops a script against the digital twin of the bench before the bench exists:
the counters answer SCPI on 127.0.0.1 (pyvisa), the FOGs stream on pseudo-terminals
(pyserial), the drives' CAN buses are served by a socketcand server on 127.0.0.1
(sims/socketcand_server.py), which python-can's `socketcand` interface opens from any
process (canopen). One line per instrument says where (CONTRACT §1):

    outer counter TCPIP0::127.0.0.1::40113::SOCKET
    outer fog /dev/pts/7
    outer drive interface=socketcand host=127.0.0.1 port=40987 channel=bench node=2

A drive line's words before `node=` are exactly `can.Bus`'s arguments (numbers as
integers). Each `bench sim` takes a free port, so two of them never share a bus, and
nothing is sent beyond this machine. The stand's clock runs in real time (clock_speed
1), whatever the stand file's `sim.clock_speed` says: a script on the other side lives
in real time. Runs until Ctrl-C or SIGTERM, then stops every twin.
"""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Iterator

from bench.app.devices import stand_config
from bench.core.config import SimSettings, StandSettings
from bench.core.engine import SignalHandler
from bench.core.registry import procedure_kind
from bench.core.simbench import SimBench, with_sim
from bench.core.simdrift import drifted, stated_run_number
from bench.core.stops import Stops

#: how `bench sim` serves its drives' buses: a bus another process can open
SIM_CAN_INTERFACE = "socketcand"


def address_lines(sim: SimBench, stand: StandSettings) -> Iterator[str]:
    """`AXIS KIND ADDRESS` for every instrument the twins serve (CONTRACT §1)."""
    for axis in sim.axes:
        ac = stand.axes[axis]
        if ac.counter:
            yield f"{axis} counter {ac.counter.resource}"
        if ac.fog:
            yield f"{axis} fog {ac.fog.port}"
        d = ac.drive
        bus = "".join(f" {k}={v}" for k, v in d.bus_options.items())
        yield f"{axis} drive interface={d.interface}{bus} channel={d.channel} node={d.node_id}"
    for where, address in stand.addresses.items():   # a kind's own instruments
        parts = where.split(".")
        if parts[:2] == ["platform", "awg"]:
            yield f"platform awg {address}"
        elif parts[:2] == ["platform", "gyros"] and len(parts) > 3:
            yield f"{parts[2]} {parts[3]} {address}"


def serve(stand_path: str, stop: threading.Event | None = None) -> int:
    """Start the twins, print their addresses, run until `stop` (or a signal)."""
    cfg = stand_config(stand_path)
    if cfg is None:
        return 2
    if not cfg.has_sim:
        print(f"{stand_path}: no `sim:` block; the twins run on built-in defaults",
              file=sys.stderr)
    cfg = with_sim(cfg, clock_speed=1, can_bus=SIM_CAN_INTERFACE)
    # a drifting twin (bench control's demonstrations) takes its run's truth; no records
    # here, so the run is the one the stand states, else the first
    sim, notes = drifted(cfg.stand_settings.sim or SimSettings(),
                         stated_run_number(cfg.stand_settings) or 1)
    for note in notes:
        print(note, file=sys.stderr)
    cfg = with_sim(cfg, axes=sim.axes)
    stop = stop or threading.Event()
    previous: dict[signal.Signals, SignalHandler] = {}
    stops = Stops()    # the twins and the socketcand server register theirs as they start
    status = 0
    try:
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                previous[sig] = signal.signal(sig, lambda *_: stop.set())
        with stops.collecting():
            simbench, served = procedure_kind(cfg.kind).steps.start_sim(cfg)
        simbench.start_clock()
        for line in address_lines(simbench, served):
            print(line, flush=True)
        print("twins running (real time); Ctrl-C stops them", file=sys.stderr, flush=True)
        while not stop.wait(0.5):
            pass
    except Exception as e:  # noqa: BLE001 - say which twin did not start
        print(f"ERROR: {e}", file=sys.stderr)
        status = 3
    finally:
        stops.run()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    for outcome in stops.failures:   # beneath the first cause, never in its place
        print(f"  also, while stopping: {outcome.text}", file=sys.stderr)
    print("twins stopped", file=sys.stderr, flush=True)
    return 3 if stops.failures else status
