"""Instrument drivers: the same code talks to real instruments and to their twins."""
