"""An axis's defaults where the stand file states none, apart from the driver
(drivers/axis.py) that applies them: the settings (bench/core/config.py DRIVE) declare
them as the keys' defaults without loading the driver, its threads and its heartbeat.
"""

from __future__ import annotations

#: the controller's heartbeat period, ms, where the stand file states none (the schema's
#: default: bench/core/config.py DRIVE)
DEFAULT_HEARTBEAT_MS = 50
#: the TPDO settings: verified at connect, not written, unless the stand says `set`
DEFAULT_PDO = "verify"
#: the drive's units: its factor group read at connect, unless the stand says what to set
DEFAULT_UNIT_FACTORS = "read"
#: how close a position move must land, deg, where the stand file does not say
DEFAULT_POSITION_TOLERANCE_DEG = 0.01
