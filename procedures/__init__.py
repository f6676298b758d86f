"""Measurement procedures the engine runs (rate ladder, drift pulse)."""
