"""The +/-w rate ladder of docs/method.md part A, as a procedure kind (a plug-in).

kind.py: files, plan and steps; settings.py: the procedure file's keys and defaults;
analysis.py: result.json from a run directory's raw data; certificate.py: its part of the
calibration certificate.
"""

from procedures.rate_ladder.kind import KIND, NAME

__all__ = ["KIND", "NAME"]
