"""Simulated twins of the bench's instruments, all sampling one simulated stand."""
