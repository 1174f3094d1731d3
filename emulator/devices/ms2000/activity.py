"""What an axis is doing (its activity, which decides the status characters) and its limit ends."""

from __future__ import annotations

from enum import Enum

UPPER = "upper"
LOWER = "lower"
LIMIT_CODES = {UPPER: 34, LOWER: 35}


class Activity(Enum):
    IDLE = "idle"
    MOVE = "move"  # M, R, ring buffer, low-level moves: right status character `m`
    HOME = "home"  # `!`: `B`
    SPIN = "spin"  # `@`: `s`
    VELOCITY = "velocity"  # VE: `s`
    MANUAL = "manual"  # joystick, wheel: not busy
    CORRECT = "correct"  # drift correction: not busy
    PATTERN = "pattern"  # a module's path (MULTIAXIS MOVES): `T`


BUSY_ACTIVITIES = (Activity.MOVE, Activity.HOME, Activity.SPIN, Activity.VELOCITY, Activity.PATTERN)
