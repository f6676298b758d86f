"""Unit factors and the one physical constant every layer shares.

They live at the bottom layer (drivers) so the simulated truth and the estimators take
them from one place without either importing the other.
"""

from __future__ import annotations

SECONDS_PER_HOUR = 3600.0
ARCSEC_PER_DEG = 3600.0
#: the Earth's rotation rate, deg/h (docs/method.md B: 15.041 deg/h)
EARTH_RATE_DPH = 15.041
