"""What an axis is doing (its activity, which decides the status characters), its limit ends and
the group of axes one command started."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import Generic, TypeVar

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


A = TypeVar("A")


@dataclass(eq=False)
class MoveGroup(Generic[A]):
    """Axes started by one command: it completes when the last of them has landed and waited
    (generic in the axis type, so that this file needs none)."""

    activity: Activity = Activity.MOVE
    axes: set[A] = field(default_factory=set)
    #: letters of the axes that completed as part of the group, in landing order
    landed: list[str] = field(default_factory=list)
