"""The engine's layer: settings (loaded once, typed), the plan, the run journal, the
instruments a session opens, the twins' wiring and the kind registry.

Imports downwards only: `bench.analysis`, `sims`, `drivers` (the contract in pyproject.toml).
"""
