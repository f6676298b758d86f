"""Measurement procedures the engine runs, as plug-ins (python-can's interfaces are the model).

A procedure kind turns a validated config into a plan, executes each step of it on the
bench, and analyzes a run directory's raw data into result.json. Each kind is its own
package here and registers itself by entry point (group `ratebench.procedures`, see
bench/core/registry.py); the engine knows nothing of rate ladders or drift pulses.
"""
