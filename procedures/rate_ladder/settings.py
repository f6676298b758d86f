"""The rate ladder's procedure file: its keys, their defaults, and the rules that read them."""

from __future__ import annotations

from typing import Any

from bench.config import (
    ACCEL_MAX_DPS2,
    COMMON_PROCEDURE_KEYS,
    RATE_MAX_DPS,
    RATE_MIN_DPS,
    STEP_MAX_S,
    Config,
)
from bench.schema import Key, ListOf, Map, MapOf, Num, Str

NAME = "rate-ladder"

BAND = Map({
    "below_dps": Key(Num(min=0, exclusive_min=True, max=RATE_MAX_DPS, unit="deg/s"), False,
                     "the band applies to rates below this; omit on the last band"),
    "rel": Key(Num(min=0, exclusive_min=True, max=1), True,
               "tolerance, a fraction (1e-6 = 1 ppm)"),
})
SETTLE = Map({
    "tolerance_dps": Key(Num(min=0, exclusive_min=True, max=100, unit="deg/s")),
    "tolerance_rel": Key(Num(min=0, exclusive_min=True, max=1)),
    "hold_s": Key(Num(min=0, max=86_400, unit="s")),
    "timeout_s": Key(Num(min=0, exclusive_min=True, max=STEP_MAX_S, unit="s")),
})
AXIS = Map({
    "rates_dps": Key(ListOf(Num(min=RATE_MIN_DPS, max=RATE_MAX_DPS, unit="deg/s"),
                            min_len=1), True),
    "turns": Key(Num(min=1, max=10_000, integer=True)),
    "prompt": Key(Str(), False, "what the operator must do before this axis"),
})
PROCEDURE = Map({
    **COMMON_PROCEDURE_KEYS,
    "turns": Key(Num(min=1, max=10_000, integer=True), False, "turns per rate and direction"),
    "sequence": Key(Str(("+-", "+-+")), False, "order of the halves of a pair"),
    "accel_dps2": Key(Num(min=0, exclusive_min=True, max=ACCEL_MAX_DPS2, unit="deg/s^2")),
    "settle": Key(SETTLE),
    "static_record_s": Key(Num(min=0, max=86_400, unit="s"), False,
                           "FOG at rest per axis (noise floor)"),
    "harmonics": Key(Num(min=1, max=20, integer=True), False, "orders 1..H fitted in angle"),
    "mains_hz": Key(Num(min=1, max=1000, unit="Hz")),
    "axes": Key(MapOf(AXIS, min_len=1), True),
    "tolerance": Key(Map({
        "rate_error": Key(ListOf(BAND, min_len=1)),
        "rate_instability": Key(ListOf(BAND, min_len=1)),
        "intra_turn_instability": Key(ListOf(BAND, min_len=1)),
    })),
})

DEFAULTS: dict[str, Any] = {
    "turns": 5,
    "sequence": "+-+",
    "static_record_s": 60.0,
    "harmonics": 4,
    "mains_hz": 50.0,
    "decision_rule": "simple",
    "prompts": True,
}
SETTLE_DEFAULTS = {"tolerance_rel": 1e-3, "tolerance_dps": 0.005, "hold_s": 2.0,
                   "timeout_s": 60.0}


def setting(cfg: Config, key: str) -> Any:
    return cfg.procedure.get(key, DEFAULTS.get(key))


def tolerance_for(bands: list[dict[str, float]] | None, rate_dps: float) -> float | None:
    """The first band whose `below_dps` exceeds |rate|, else the band without one."""
    if not bands:
        return None
    for band in bands:
        if "below_dps" in band and abs(rate_dps) < band["below_dps"]:
            return float(band["rel"])
    for band in bands:
        if "below_dps" not in band:
            return float(band["rel"])
    return None


def halves(turns: int, sequence: str) -> list[tuple[int, int]]:
    """(sign, turns) per half. '+-+' splits the + turns around the - half."""
    if sequence == "+-+" and turns >= 2:
        return [(+1, (turns + 1) // 2), (-1, turns), (+1, turns // 2)]
    return [(+1, turns), (-1, turns)]
