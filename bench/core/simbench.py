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

import dataclasses
import functools
import sys
import uuid
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Protocol, TypeAlias, TypedDict, Unpack

import msgspec
import numpy as np

from bench.core.config import (
    Config,
    CounterSettings,
    SimAxis,
    SimSettings,
    StandAxis,
    StandSettings,
)
from bench.core.stops import StopOutcome, Stops
from drivers.waits import MIN_REAL_MARGIN_S
from sims.clock import GIL_SWITCH_S, MAX, SteppedClock, make_clock, parse_speed
from sims.counter_twin import CounterTwin, SyncLink
from sims.fog_twin import FogTwin
from sims.stand import SimulatedStand, StandTruth

# the drive twin and the socketcand server (canopen, python-can) are imported when the
# twins start: a kind's module imports this one, and `bench validate` loads the kind
if TYPE_CHECKING:
    from sims.drive_twin import DriveTwin
    from sims.socketcand_server import SocketcandServer

#: the stand's sample rate for an axis that carries no FOG (the twins' time grid)
SIM_GRID_HZ = 1000.0

TwinFactory = Callable[["SimBench"], None]



def for_session(cfg: Config, session: int) -> Config:
    """`cfg` with its twins set up for session `session` of a run (`session_seed`)."""
    return with_sim(cfg, session=int(session))


class KindTwin(Protocol):
    """A twin a procedure kind starts for instruments of its own (a gyro platform's rig):
    the bench registers its stop and keeps it by name."""

    def stop(self) -> None: ...


#: a twin the simulated bench keeps by name ("outer.drive", "gyro-rig")
Twin: TypeAlias = "FogTwin | DriveTwin | CounterTwin | KindTwin"


class SimChanges(TypedDict, total=False):
    """What `with_sim` may change of a stand's `sim:` settings."""

    session: int
    clock_speed: float | str | None
    can_bus: str
    axes: Mapping[str, SimAxis]


def with_sim(cfg: Config, **changes: Unpack[SimChanges]) -> Config:
    """`cfg` whose parsed stand has its `sim:` settings changed (a copy; the stand file's
    own mapping, copied into the run directory, stays as written)."""
    stand = cfg.stand_settings
    sim = msgspec.structs.replace(stand.sim or SimSettings(), **changes)
    out = dataclasses.replace(cfg)
    out.__dict__["stand_settings"] = dataclasses.replace(stand, sim=sim)
    return out


def session_seed(sim: SimSettings) -> int:
    """The twins' seed for this session: the stand's for the first; for a --resume,
    one derived from (seed, session). Each session's clock starts at stand time 0, so with
    the stand's seed session 2 would replay session 1's noise sample for sample and the
    halves measured in the two sessions would share it. Deterministic all the same."""
    if sim.session <= 1:
        return sim.seed
    return int(np.random.SeedSequence([sim.seed, sim.session]).generate_state(1)[0])
def sync_link(counter: CounterSettings, sim_axis: SimAxis) -> SyncLink | None:
    """The FOG-sync-to-counter link the twins model for a `fog-sync` time tie: pulses
    every `sync_period_s`, the sim truth's latency and jitter (default: exactly the
    latency the stand declares). None when the stand ties otherwise (nothing wired)."""
    tie = counter.time_tie
    if tie is None or tie.source != "fog-sync":
        return None
    latency = sim_axis.tie_latency_s
    return SyncLink(period_s=tie.sync_period_s,
                    latency_s=tie.latency_s if latency is None else latency,
                    jitter_s=sim_axis.tie_jitter_s)


class SimBench:
    """Owns the stand, the clock and the twins; a context manager that stops them all."""

    def __init__(self, stand: StandSettings, axes: list[str] | None = None) -> None:
        self.settings = stand
        self.sim = stand.sim or SimSettings()
        axes = axes if axes is not None else list(stand.axes)
        truth = StandTruth(
            seed=session_seed(self.sim),
            axes={a: self.sim.axis(a).truth for a in axes},
            clock_speed=parse_speed(self.sim.clock_speed, MAX),
        )
        # `clock_speed: max` (the default): the co-simulation, deterministic; N: paced
        self.clock = make_clock(truth.clock_speed, running=False)
        # an axis with no FOG is still sampled, on a grid of its own (SIM_GRID_HZ)
        fog_hz = {a: f.rate_hz if (f := stand.axes[a].fog) else SIM_GRID_HZ for a in axes}
        self.stand = SimulatedStand(truth, fog_hz, self.clock)
        self.axes = axes
        self.channel = f"sim-{uuid.uuid4().hex[:8]}"
        #: the twins' bus in this process; `sim.can_bus: socketcand` (`bench sim`) also
        #: serves each bus to other processes on 127.0.0.1 (sims/socketcand_server.py)
        self.can_interface = "virtual"
        self.can_server: SocketcandServer | None = None
        self.twins: dict[str, Twin] = {}
        #: a kind's own instruments' addresses, rewritten to their twins' (`address`)
        self.addresses: dict[str, str] = {}
        #: every twin's stop, registered as it starts (bench/core/stops.py); itself
        #: registered with the command's registry as the simulated bench is made
        self.stops = Stops.child("the simulated bench", "twin")
        self.stops.add("the stand's clock", self.clock.pause, "clock")  # the last stop
        if isinstance(self.clock, SteppedClock):  # hand-offs every step (sims/clock.py)
            switch = sys.getswitchinterval()
            sys.setswitchinterval(GIL_SWITCH_S)
            self.stops.add("the interpreter's switch interval",
                           functools.partial(sys.setswitchinterval, switch), "clock")

    def start(self, extra: list[TwinFactory] | None = None) -> StandSettings:
        """Start every twin; return the stand settings pointing at them."""
        from sims.drive_twin import DriveTwin
        axes = dict(self.settings.axes)
        try:
            for a in self.axes:  # FOG twins first: they must see every sample from 0 on
                fs = axes[a].fog
                if fs:
                    ft = FogTwin(self.stand, a, fs)
                    axes[a] = dataclasses.replace(
                        axes[a], fog=msgspec.structs.replace(fs, port=ft.start()))
                    self.stops.add(f"{a} FOG twin", ft.stop, "twin")
                    # the stand runs no faster than this FOG's frames go out (sims/clock.py)
                    self.stops.add(f"{a} FOG twin's pace", self.clock.pace(ft.delivered_s),
                                   "clock")
                    self.twins[f"{a}.fog"] = ft
            # served to other processes (socketcand): one virtual bus per CAN bus of the
            # stand file, the same axes sharing one, as on the real bench. In this process
            # each axis's drive and controller have a channel of their own: python-can's
            # virtual bus copies every frame to every other node on a channel and wakes its
            # thread (issue 62: 2 of 3 copies thrown away, half the stepping thread's CPU),
            # and no frame of one axis is for the other's nodes (node ids are distinct per
            # bus, bench/core/canbus.py; the drivers send no broadcast, SYNC or NMT to all)
            shared = self.sim.can_bus == "socketcand"
            buses: dict[str, str] = {}
            for a in self.axes:
                d = axes[a].drive
                truth = self.sim.axis(a)
                channel = buses.setdefault(d.bus if shared else f"{d.bus} {a}",
                                           f"{self.channel}-{len(buses)}")
                twin = DriveTwin(self.stand, a, msgspec.structs.replace(
                    d, interface=self.can_interface, channel=channel, host=None, port=None,
                    bitrate=None), truth.drive)
                self.stops.enter(twin, f"{a} drive twin", "twin")
                # a real drive outlives the controller that left it: before the twin
                # stops, its watchdog acts on a power stage left on (after every
                # controller's stop, which the command's registry ran first)
                self.stops.add(f"{a} drive twin's watchdog", twin.settle_after_controller,
                               "twin")
                self.twins[f"{a}.drive"] = twin
                # the twin shares this process with the controller: a starved host stalls
                # both, so its watchdog allows the bench's stated real-time minimum
                watchdog = d.watchdog_ms if d.watchdog_ms is not None else 5 * d.heartbeat_ms
                drive = msgspec.structs.replace(
                    d, interface=self.can_interface, channel=channel,
                    watchdog_ms=max(watchdog, int(MIN_REAL_MARGIN_S * 1000)))
                axes[a] = dataclasses.replace(axes[a], drive=drive)
                c = axes[a].counter
                if c:
                    # the twin reads its truth whole from the stand's axis
                    ct = CounterTwin(self.stand, a, c, sync=sync_link(c, truth),
                                     seed=session_seed(self.sim))
                    resource = ct.start()
                    self.stops.add(f"{a} counter twin", ct.stop, "twin")
                    self.twins[f"{a}.counter"] = ct
                    # the twin knows its zero-mark signal: mid-swing is a sound level
                    level = c.level_v if c.level_v is not None else sum(ct.signal_v) / 2
                    axes[a] = dataclasses.replace(axes[a], counter=msgspec.structs.replace(
                        c, resource=resource, level_v=level))
            if self.sim.can_bus == "socketcand":
                axes = self._serve_buses(axes, buses)
            for factory in extra or []:
                factory(self)
        except BaseException:
            self.stop()
            raise
        return dataclasses.replace(self.settings, axes=axes,
                                   addresses=dict(self.addresses))

    def _serve_buses(self, axes: dict[str, StandAxis],
                     buses: dict[str, str]) -> dict[str, StandAxis]:
        """Serve each of the stand's buses on one socketcand server on 127.0.0.1, and
        point the drives at it: what another process opens with `can.Bus`. A bus keeps
        the stand's channel name where socketcand allows it (16 characters)."""
        from sims.socketcand_server import MAX_BUS_NAME, SocketcandServer
        names: dict[str, str] = {}          # the stand's bus -> its socketcand bus name
        for n, bus in enumerate(buses):
            stated = bus.split(":", 1)[1]
            ok = (0 < len(stated) <= MAX_BUS_NAME and not set(stated) & set(" <>")
                  and stated not in names.values())
            names[bus] = stated if ok else f"can{n}"
        server = SocketcandServer({names[b]: ch for b, ch in buses.items()})
        port = server.start()
        self.stops.add("the socketcand server", server.stop, "server")
        self.can_server = server
        out = dict(axes)
        for a in self.axes:
            d = axes[a].drive
            original = self.settings.axes[a].drive
            out[a] = dataclasses.replace(axes[a], drive=msgspec.structs.replace(
                d, interface="socketcand", channel=names[original.bus],
                host=server.host, port=port))
        return out

    def add(self, name: str, twin: KindTwin, stop: Callable[[], None]) -> None:
        """For procedure kinds with instruments of their own (e.g. a gyro platform's):
        the twin, started, and its stop."""
        self.twins[name] = twin
        self.stops.add(name, stop, "twin")

    def start_clock(self) -> None:
        """The instruments are open: time may pass; on the co-simulation, what the stand
        holds up to now is with the drivers before the first step looks at it."""
        self.clock.start()
        if isinstance(self.clock, SteppedClock):
            self.clock.drain()

    def stop(self) -> tuple[StopOutcome, ...]:
        """Stop every twin (each drive's watchdog let act first), last started first, then
        the clock; safe twice. The outcomes, raises none."""
        return self.stops.run()

    def __enter__(self) -> SimBench:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
