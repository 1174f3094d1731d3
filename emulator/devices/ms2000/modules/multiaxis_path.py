"""Geometry and timing of MULTIAXIS MOVES patterns (§9.13, MS-MULTI-1), free of the controller.

A pattern is a curve P(θ) in machine mm: a circle of radius R about a centre (fast circles, circle),
the same circle with Z rising by the width per turn (helix), or a spiral whose radius grows by the
width per turn from the centre up to R. The stage runs along it at the path speed, counter-clockwise
[choice], optionally ramping the speed over the axes' `AC` time. `PathMotion` steps along the curve
in servo-sized steps (at most 5° or 50 ms each); `segments` turns a run of steps into one axis's
constant-acceleration segments through the sampled points, so the motion model follows the curve.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum
from itertools import pairwise

from emulator.devices.ms2000.trajectory import Segment

TAU = 2 * math.pi
#: longest step along the curve, in angle and in time
MAX_STEP_ANGLE = TAU / 72
MAX_STEP_S = 0.05
#: while ramping down towards the end of a cycle the speed stays above this share of the path
#: speed, so the ramp's end is reached however the arc length was estimated
CREEP_SHARE = 0.02


class Pattern(Enum):
    """Bits 7–6 of `MM F` (MS-MULTI-1)."""

    FAST_CIRCLES = 0
    CIRCLE = 1
    HELIX = 2
    SPIRAL = 3


@dataclass(frozen=True)
class Geometry:
    pattern: Pattern
    centre_x: float
    centre_y: float
    z0: float
    radius: float
    width: float

    def cycle_angle(self) -> float:
        """θ at the end of one cycle: one turn, or as many turns as the spiral needs to reach R."""
        return TAU * self.radius / self.width if self.pattern is Pattern.SPIRAL else TAU

    def _radius(self, theta: float) -> tuple[float, float]:
        """r(θ) and dr/dθ; a repeating spiral goes out and in again (a triangle wave) [choice]."""
        if self.pattern is not Pattern.SPIRAL:
            return self.radius, 0.0
        grown = self.width * theta / TAU
        turn, within = divmod(grown, self.radius)
        rate = self.width / TAU
        return (within, rate) if int(turn) % 2 == 0 else (self.radius - within, -rate)

    def point(self, theta: float) -> tuple[float, float, float]:
        r, _ = self._radius(theta)
        z = self.z0 + self.width * theta / TAU if self.pattern is Pattern.HELIX else self.z0
        return self.centre_x + r * math.cos(theta), self.centre_y + r * math.sin(theta), z

    def tangent(self, theta: float) -> tuple[float, float, float]:
        """dP/dθ."""
        r, dr = self._radius(theta)
        c, s = math.cos(theta), math.sin(theta)
        dz = self.width / TAU if self.pattern is Pattern.HELIX else 0.0
        return dr * c - r * s, dr * s + r * c, dz

    def rho(self, theta: float) -> float:
        """XY path length per radian: the path speed is measured in the XY plane."""
        dx, dy, _ = self.tangent(theta)
        return math.hypot(dx, dy)


@dataclass(frozen=True)
class Sample:
    t: float
    theta: float
    speed: float  # path speed (mm/s)


@dataclass
class PathMotion:
    """Where the stage is along a pattern and how fast it goes; `step` moves it on."""

    geometry: Geometry
    speed: float
    #: mm/s² of the speed ramps; None: the speed jumps (mode bit 1 clear)
    accel: float | None
    #: mm/s² of a stop (`MM R=80`): always ramped [choice]
    stop_accel: float
    end_theta: float  # math.inf while repeating
    now: Sample
    stopping: bool = False
    finished: bool = False

    def _next_speed(self, dt: float, rho: float) -> float:
        v = self.now.speed
        if self.stopping:
            return max(v - self.stop_accel * dt, 0.0)
        if self.accel is None:
            return self.speed
        remaining = (self.end_theta - self.now.theta) * rho
        if remaining <= v * v / (2 * self.accel) + v * dt:
            return max(v - self.accel * dt, CREEP_SHARE * self.speed)
        return min(v + self.accel * dt, self.speed)

    def step(self, servo_s: float) -> Sample:
        """One step along the curve; `finished` once the cycle's end or a stop is reached."""
        here = self.now
        rho = max(self.geometry.rho(here.theta), 1e-12)
        pace = max(here.speed, CREEP_SHARE * self.speed) / rho
        dt = min(max(MAX_STEP_ANGLE / pace, servo_s), MAX_STEP_S)
        v_next = self._next_speed(dt, rho)
        dtheta = (here.speed + v_next) / 2 * dt / rho
        if self.stopping and v_next == 0:
            self.finished = True
        if here.theta + dtheta >= self.end_theta:
            dt *= (self.end_theta - here.theta) / dtheta
            dtheta = self.end_theta - here.theta
            self.finished = True
        self.now = Sample(here.t + dt, here.theta + dtheta, v_next)
        return self.now

    def velocity(self, sample: Sample) -> tuple[float, float, float]:
        """The stage's velocity (mm/s per axis) at a sample."""
        rho = max(self.geometry.rho(sample.theta), 1e-12)
        omega = sample.speed / rho
        dx, dy, dz = self.geometry.tangent(sample.theta)
        return dx * omega, dy * omega, dz * omega


def segments(motion: PathMotion, samples: list[Sample], axis: int, counts_per_mm: float) -> list[Segment]:
    """Segments of one axis (0 X, 1 Y, 2 Z) through consecutive samples: each starts at its sample's
    position and velocity and lands exactly on the next sample's position."""
    out: list[Segment] = []
    for here, there in pairwise(samples):
        dt = there.t - here.t
        if dt <= 0:
            continue
        x0 = motion.geometry.point(here.theta)[axis] * counts_per_mm
        x1 = motion.geometry.point(there.theta)[axis] * counts_per_mm
        v0 = motion.velocity(here)[axis] * counts_per_mm
        out.append(Segment(here.t, dt, x0, v0, 2 * (x1 - x0 - v0 * dt) / (dt * dt)))
    return out
