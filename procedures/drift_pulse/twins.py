"""The drift-pulse bench's twins on the simulated stand: the gyro platform on the stand's
turntable, its waveform generator and one DMM per gyro (sims/gyro_rig.py), added to the
simulated bench (`bench.core.simbench.SimBench.start(extra=[...])`) with each address in the
stand mapping rewritten to its twin's.
"""

from __future__ import annotations

from bench.core.simbench import SimBench, TwinFactory
from sims.gyro_rig import start_gyro_rig
from sims.platform import GyroTruth, PlatformTruth

#: the keys of a stand file's `sim.platform.gyros.<gyro>` truth (the gyro twin's fields)
SIM_GYRO_KEYS: tuple[str, ...] = tuple(GyroTruth.__dataclass_fields__)


def gyro_rig_factory(gyros: list[str]) -> TwinFactory:
    """The twins of a gyro platform on the stand's turntable (the stand file's `platform:`
    and `sim.platform` blocks): the platform, its waveform generator and one DMM per gyro
    in `gyros`, each address rewritten to its twin's."""

    def add_platform(sb: SimBench) -> None:
        plat = sb.stand_cfg["platform"]
        sim_cfg = sb.stand_cfg.get("sim") or {}
        sp = sim_cfg["platform"]
        truth = PlatformTruth.from_mapping(
            {**sp, "gyros": {g: sp["gyros"][g] for g in gyros},
             "table_axis": plat["table_axis"]},
            seed=int(sim_cfg.get("seed", 0)))  # the platform's drift walk is its truth
        awg_options = dict(sim_cfg.get("awg") or {})
        dmm_options = dict(sim_cfg.get("dmm") or {})
        awg_serial, dmm_serials = awg_options.pop("serial", None), dmm_options.pop("serials", {})
        rig = start_gyro_rig(sb.stand, truth,
                             {g: plat["gyros"][g]["awg_channel"] for g in gyros},
                             awg_model=plat["awg"]["model"],
                             dmm_model=plat["gyros"][gyros[0]]["dmm"]["model"],
                             awg_options=awg_options, dmm_options=dmm_options)
        sb.add("gyro-rig", rig, rig.stop)
        # the stand's serials in *IDN? field 3 (each twin reads its idn at every query)
        for twin, serial in ((rig.awg, awg_serial),
                             *((rig.dmms[g], dmm_serials.get(g)) for g in gyros)):
            if serial:
                idn = twin.idn.split(",")
                twin.idn = ",".join([*idn[:2], str(serial), *idn[3:]])
        plat["awg"]["resource"] = rig.awg.resource
        for g in gyros:
            plat["gyros"][g]["dmm"]["resource"] = rig.dmms[g].resource

    return add_platform
