"""Kinematics shared by device models: a symmetric trapezoidal (or triangular) move along one path.

A move of `distance` at cruise speed `speed` with ramp time `ramp` (rest to cruise speed; 0 = no
acceleration, i.e. constant speed from start to end) takes `distance / speed + ramp` when the
distance allows reaching cruise speed (`distance >= speed * ramp`), else `2 * sqrt(distance * ramp
/ speed)` (triangular). Units are the caller's (µm, mm, counts...) and seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Trapezoid:
    distance: float
    speed: float
    ramp: float = 0.0

    def __post_init__(self) -> None:
        if self.distance < 0 or self.speed <= 0 or self.ramp < 0:
            raise ValueError(f"bad move: distance {self.distance}, speed {self.speed}, ramp {self.ramp}")

    @property
    def accel(self) -> float:
        return math.inf if self.ramp == 0 else self.speed / self.ramp

    @property
    def triangular(self) -> bool:
        return self.ramp > 0 and self.distance < self.speed * self.ramp

    @property
    def ramp_time(self) -> float:
        """Duration of each ramp (acceleration and deceleration)."""
        if self.ramp == 0:
            return 0.0
        return math.sqrt(self.distance / self.accel) if self.triangular else self.ramp

    @property
    def peak_speed(self) -> float:
        return self.accel * self.ramp_time if self.triangular else self.speed

    @property
    def duration(self) -> float:
        if self.distance == 0:
            return 0.0
        if self.triangular:
            return 2 * self.ramp_time
        return self.distance / self.speed + self.ramp

    def covered(self, t: float) -> float:
        """Distance covered `t` seconds after the start (clipped to [0, distance])."""
        total = self.duration
        if t <= 0 or total == 0:
            return 0.0
        if t >= total:
            return self.distance
        ramp = self.ramp_time
        peak = self.peak_speed
        if ramp == 0:
            return self.speed * t
        if t < ramp:
            return 0.5 * self.accel * t * t
        ramp_distance = 0.5 * peak * ramp
        if t <= total - ramp:
            return ramp_distance + peak * (t - ramp)
        left = total - t
        return self.distance - 0.5 * self.accel * left * left

    def fraction(self, t: float) -> float:
        """Share of the distance covered at `t`, in [0, 1] (1 for a zero-length move)."""
        return 1.0 if self.distance == 0 else self.covered(t) / self.distance

    def velocity(self, t: float) -> float:
        total = self.duration
        if t <= 0 or t >= total:
            return 0.0
        ramp = self.ramp_time
        if ramp == 0:
            return self.speed
        if t < ramp:
            return self.accel * t
        if t <= total - ramp:
            return self.peak_speed
        return self.accel * (total - t)
