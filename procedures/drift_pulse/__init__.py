"""Gyro drift by alternating-sign pulses (docs/method.md part B), as a procedure kind.

kind.py: files, plan, steps and the analysis; certificate.py: its part of the
calibration certificate.
"""

from procedures.drift_pulse.kind import KIND, NAME

__all__ = ["KIND", "NAME"]
