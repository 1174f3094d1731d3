"""Rounding as both controller families' firmware does it: halves away from zero.

A module of its own because the MP-285 codec (µm to µsteps, STEP fields) and the emulator's models
of both families (positions, times, MS2000 settings) must round alike.
"""

from __future__ import annotations


def round_half_away(value: float) -> int:
    """Nearest integer, halves away from zero."""
    magnitude = int(abs(value) + 0.5)
    return magnitude if value >= 0 else -magnitude
