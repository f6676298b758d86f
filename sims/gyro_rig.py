"""The drift-pulse bench's twins, wired as on the bench: one platform on the stand's
turntable, one waveform generator whose channels drive the gyros' torque sensors, one
digitizing DMM per gyro on its angle sensor, every DMM's Ext Trig on the generator's
trigger output (a BNC tee)."""

from __future__ import annotations

import contextlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from sims.awg_twin import AwgTwin
from sims.dmm_twin import DmmTwin
from sims.platform import GyroPlatform, PlatformTruth
from sims.stand import SimulatedStand


@dataclass
class GyroRig:
    platform: GyroPlatform
    awg: AwgTwin
    dmms: dict[str, DmmTwin] = field(default_factory=dict)

    def stop(self) -> None:
        for twin in (*self.dmms.values(), self.awg):
            with contextlib.suppress(Exception):
                twin.stop()


def start_gyro_rig(stand: SimulatedStand, truth: PlatformTruth, channels: Mapping[str, int],
                   *, awg_model: str = "keysight-33500b", dmm_model: str = "keysight-34465a",
                   awg_options: Mapping[str, Any] | None = None,
                   dmm_options: Mapping[str, Any] | None = None,
                   dmm_errors: Mapping[str, Mapping[str, float]] | None = None) -> GyroRig:
    """Start the twins; `channels` maps each gyro to its generator channel, `dmm_errors`
    each gyro's DMM to its own errors (DmmTwin's gain_error_rel, offset_error_v)."""
    platform = GyroPlatform(truth, stand)
    awg = AwgTwin(platform, {ch: g for g, ch in channels.items()}, awg_model,
                  **(awg_options or {}))
    rig = GyroRig(platform, awg)
    try:
        awg.start()
        for gyro in channels:
            errors = (dmm_errors or {}).get(gyro, {})
            dmm = DmmTwin(platform, gyro, dmm_model, **(dmm_options or {}),
                          gain_error_rel=errors.get("gain_error_rel", 0.0),
                          offset_error_v=errors.get("offset_error_v", 0.0))
            dmm.start()
            rig.dmms[gyro] = dmm
            awg.trigger_out.append(dmm.external_trigger)
    except BaseException:
        rig.stop()
        raise
    return rig
