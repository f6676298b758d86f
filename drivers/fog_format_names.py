"""The FOG frame formats' names, apart from the formats (drivers/fog_formats.py builds each
under its name here): a stand file's `fog.format` is checked against them without loading
numpy, which the formats' record layouts need (bench/core/config.py)."""

from __future__ import annotations

KVH_A = "kvh-a"
KVH_B = "kvh-b"
#: every format drivers/fog_formats.py knows, in its FORMATS order
FORMAT_NAMES: tuple[str, ...] = (KVH_A, KVH_B)
