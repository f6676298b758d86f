"""The one test of "is this a number to print or record" for values read back from files."""

from __future__ import annotations

import math
from typing import SupportsFloat, SupportsIndex


def finite_number(x: object) -> float | None:
    """A finite float, or None (missing, text, NaN, inf, a bool): result.json and journals
    are read back by the certificate, the DCC and the records, and a damaged or partial
    file must give 'no value', never a crash or a NaN printed as a figure."""
    if x is None or isinstance(x, bool) \
            or not isinstance(x, SupportsFloat | SupportsIndex | str | bytes):
        return None     # what float() refuses anyway
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None
