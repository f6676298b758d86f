"""Rate-table attestation bench: procedure engine, CLI, run records and certificate."""

__version__ = "0.1.0"
