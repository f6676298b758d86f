"""The simulated bench: one simulated stand, its virtual clock, and every twin on its
real channel (SCPI on 127.0.0.1, the FOG on a pseudo-terminal, the drive on a python-can
virtual bus).

`SimBench.start()` returns the stand mapping with each instrument's address rewritten to
its twin's, so `bench.core.instruments` opens them exactly as it would open hardware. The
clock starts paused: the twins and drivers connect first, then `start_clock()`, so the
FOG's first frame is the stand's sample 0 and all instruments share one time axis.

The clock is the co-simulation's (sims/clock.py SteppedClock) unless the stand file asks
for a real-time pace (`sim: clock_speed: N`): then results depend only on the seed and
the files, never on the machine's load.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import socket
import sys
import uuid
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from bench.core.canbus import bus_name, controller_node_ids
from bench.core.config import Config, FogSettings
from drivers.waits import MIN_REAL_MARGIN_S
from sims.clock import GIL_SWITCH_S, MAX, SteppedClock, make_clock, parse_speed
from sims.counter_twin import CounterTwin
from sims.drive_twin import DriveTwin
from sims.fog_twin import FogTwin
from sims.stand import AxisTruth, SimulatedStand, StandTruth

#: the stand's sample rate for an axis that carries no FOG (the twins' time grid)
SIM_GRID_HZ = 1000.0

#: truth used by `--sim` for an axis the stand file's `sim:` block does not describe
DEFAULT_AXIS_TRUTH: dict[str, Any] = {
    "fog": {"noise_dps": 0.01},
    "turn_jitter_s": 27e-9,
}

TwinFactory = Callable[["SimBench"], None]

#: `sim.can_bus` (set by `bench sim`): the python-can interface the drive twins join;
#: "virtual" (in-process, the default) or "udp_multicast" (another process can join)
CAN_BUS_KEY = "can_bus"
#: `sim.session` (set by the run for a --resume): the session these twins serve
SESSION_KEY = "session"


def for_session(cfg: Config, session: int) -> Config:
    """`cfg` with its twins set up for session `session` of a run (`session_seed`)."""
    stand = copy.deepcopy(cfg.stand)
    stand["sim"] = {**(stand.get("sim") or {}), SESSION_KEY: int(session)}
    return dataclasses.replace(cfg, stand=stand)


def session_seed(sim: Mapping[str, Any]) -> int:
    """The twins' seed for this session: the stand's for the first; for a --resume,
    one derived from (seed, session). Each session's clock starts at stand time 0, so with
    the stand's seed session 2 would replay session 1's noise sample for sample and the
    halves measured in the two sessions would share it. Deterministic all the same."""
    seed, session = int(sim.get("seed", 0)), int(sim.get(SESSION_KEY, 1))
    if session <= 1:
        return seed
    return int(np.random.SeedSequence([seed, session]).generate_state(1)[0])
#: the multicast group of the first CAN bus of a stand on udp_multicast (one more a bus)
UDP_MULTICAST_GROUP = "239.74.163.{n}"


def _free_udp_port() -> int:
    """A UDP port no one on this host uses now: one `bench sim` a port, so two of them
    (or a test beside one) never hear each other's frames."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("", 0))
        return int(s.getsockname()[1])


def sync_link(counter_cfg: dict[str, Any], sim_axis: dict[str, Any]) -> Any:
    """The FOG-sync-to-counter link the twins model for a `fog-sync` time tie: pulses
    every `sync_period_s`, the sim truth's latency and jitter (default: exactly the
    latency the stand declares). None when the stand ties otherwise (nothing wired)."""
    from sims.counter_twin import SyncLink

    tie = counter_cfg.get("time_tie") or {}
    if tie.get("source") != "fog-sync":
        return None
    truth = sim_axis.get("time_tie") or {}
    return SyncLink(period_s=float(tie.get("sync_period_s", 1.0)),
                    latency_s=float(truth.get("latency_s", tie.get("latency_s", 0.0))),
                    jitter_s=float(truth.get("jitter_s", 0.0)))


def twin_fog_units(fog_cfg: dict[str, Any], sim_axis: dict[str, Any]) -> str:
    """What the FOG twin carries before the bench talks to it: the sim truth's
    `fog.units`, else a declared `fog.units` (a FOG configured earlier), else the KVH
    power-on default, delta radians (drivers/kvh_config.py)."""
    from drivers.kvh_config import POWER_ON_UNITS

    truth = (sim_axis.get("fog") or {}).get("units")
    if truth:
        return str(truth)
    if fog_cfg.get("configure", "declare") == "declare" and fog_cfg.get("units"):
        return str(fog_cfg["units"])
    return POWER_ON_UNITS


class SimBench:
    """Owns the stand, the clock and the twins; a context manager that stops them all."""

    def __init__(self, stand_cfg: dict[str, Any], axes: list[str] | None = None) -> None:
        self.stand_cfg = copy.deepcopy(stand_cfg)
        sim = self.stand_cfg.get("sim") or {}
        axes = axes if axes is not None else list(self.stand_cfg["axes"])
        sim_axes = sim.get("axes") or {}
        truth = StandTruth(
            seed=session_seed(sim),
            axes={a: AxisTruth.from_mapping(sim_axes.get(a, DEFAULT_AXIS_TRUTH)) for a in axes},
            clock_speed=parse_speed(sim.get("clock_speed"), MAX),
        )
        # `clock_speed: max` (the default): the co-simulation, deterministic; N: paced
        self.clock = make_clock(truth.clock_speed, running=False)
        fogs = {a: FogSettings.of_axis(self.stand_cfg, a) for a in axes}
        # an axis with no FOG is still sampled, on a grid of its own (SIM_GRID_HZ)
        fog_hz = {a: f.rate_hz if f else SIM_GRID_HZ for a, f in fogs.items()}
        self.stand = SimulatedStand(truth, fog_hz, self.clock)
        self.axes = axes
        self._sim_axes = sim_axes
        self.channel = f"sim-{uuid.uuid4().hex[:8]}"
        self.can_interface = str(sim.get(CAN_BUS_KEY, "virtual"))
        self.can_port = _free_udp_port() if self.can_interface == "udp_multicast" else None
        self.twins: dict[str, Any] = {}
        self._stack = contextlib.ExitStack()
        if isinstance(self.clock, SteppedClock):  # hand-offs every step (sims/clock.py)
            switch = sys.getswitchinterval()
            sys.setswitchinterval(GIL_SWITCH_S)
            self._stack.callback(sys.setswitchinterval, switch)

    def start(self, extra: list[TwinFactory] | None = None) -> dict[str, Any]:
        """Start every twin; return the stand mapping pointing at them."""
        cfg = self.stand_cfg
        sim = cfg.get("sim") or {}
        sim_axes = self._sim_axes
        try:
            for a in self.axes:  # FOG twins first: they must see every sample from 0 on
                f = cfg["axes"][a].get("fog")
                if f:
                    fs = FogSettings.of(f)
                    ft = FogTwin(self.stand, a, fmt=fs.format, axis_letter=fs.axis,
                                 units=twin_fog_units(f, sim_axes.get(a) or {}))
                    f["port"] = ft.start()
                    self._stack.callback(ft.stop)
                    # the stand runs no faster than this FOG's frames go out (sims/clock.py)
                    self._stack.callback(self.clock.pace(ft.delivered_s))
                    self.twins[f"{a}.fog"] = ft
            # one virtual bus per CAN bus of the stand file: the same axes share one, so
            # the node ids (and each axis's controller id) are those of the real bench
            controllers = controller_node_ids(cfg["axes"])
            buses: dict[str, str] = {}
            for a in self.axes:
                ac = cfg["axes"][a]
                d = ac["drive"]
                channel = buses.setdefault(bus_name(d), self._bus_channel(len(buses)))
                drive_truth = (sim_axes.get(a) or {}).get("drive") or {}
                serials = (sim_axes.get(a) or {}).get("serials") or {}
                bus_options = {"port": self.can_port} if self.can_port is not None else {}
                serial_kw: dict[str, Any] = ({"serial_number": int(serials["drive"])}
                                             if "drive" in serials else {})
                twin = DriveTwin(self.stand, a, interface=self.can_interface, channel=channel,
                                 bus_options=bus_options,
                                 node_id=d["node_id"], controller_node_id=controllers[a],
                                 **{k: drive_truth[k] for k in ("velocity_unit",
                                                                "acceleration_unit",
                                                                "tpdo_event_timer_ms")
                                    if k in drive_truth},
                                 **({"counts_per_rev": d["counts_per_rev"]}
                                    if "counts_per_rev" in d else {}),
                                 **serial_kw)
                self._stack.enter_context(twin)
                self.twins[f"{a}.drive"] = twin
                d["interface"], d["channel"] = self.can_interface, channel
                # the twin shares this process with the controller: a starved host stalls
                # both, so its watchdog allows the bench's stated real-time minimum
                hb_ms = d.get("heartbeat_ms", 50)
                d["watchdog_ms"] = max(int(d.get("watchdog_ms", 5 * hb_ms)),
                                       int(MIN_REAL_MARGIN_S * 1000))
                if ac.get("counter"):
                    c = ac["counter"]
                    ct = CounterTwin(self.stand, a, model=c["model"],
                                     sync=sync_link(c, sim_axes.get(a) or {}),
                                     seed=session_seed(sim),
                                     external_reference=bool((sim_axes.get(a) or {}).get(
                                         "counter_external_reference", True)),
                                     first_value=str((sim_axes.get(a) or {}).get(
                                         "counter_first_value", "from-start")))
                    if serials.get("counter"):    # the stand's serial in *IDN? field 3
                        idn = ct.idn.split(",")
                        ct.idn = ",".join([*idn[:2], str(serials["counter"]), *idn[3:]])
                    c["resource"] = ct.start()
                    # the twin knows its zero-mark signal: mid-swing is a sound level
                    c.setdefault("level_v", sum(ct.signal_v) / 2)
                    self._stack.callback(ct.stop)
                    self.twins[f"{a}.counter"] = ct
            for factory in extra or []:
                factory(self)
        except BaseException:
            self.stop()
            raise
        return cfg

    def _bus_channel(self, n: int) -> str:
        if self.can_interface == "udp_multicast":
            return UDP_MULTICAST_GROUP.format(n=2 + n)
        return f"{self.channel}-{n}"

    def add(self, name: str, twin: Any, stop: Callable[[], Any]) -> None:
        """For procedure kinds with instruments of their own (their `TwinFactory`, given
        to `start`, e.g. procedures/drift_pulse/twins.py)."""
        self.twins[name] = twin
        self._stack.callback(stop)

    def start_clock(self) -> None:
        self.clock.start()

    def stop(self) -> None:
        for twin in self.twins.values():
            if hasattr(twin, "settle_after_controller"):
                twin.settle_after_controller()
        self._stack.close()
        self.clock.pause()

    def __enter__(self) -> SimBench:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
