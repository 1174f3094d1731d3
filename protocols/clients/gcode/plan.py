"""What a G-code program becomes: a plan of steps in stage millimetres, and the arc chording.

A plan is a list of `Move` (straight segments: rapid or at a feed), `Dwell` and `Output` (the TTL
output that M03/M05 drive) steps, each carrying the program line it came from. Arcs arrive here
already broken into chords whose sagitta is at most `SAGITTA_MM` (0.5 µm, MS-TRACER-5).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

AXES = ("X", "Y", "Z")
#: MS-TRACER-5: an arc's chords stray from it by at most this (mm)
SAGITTA_MM = 0.0005
#: a coordinate difference below this is no motion (mm): far below one encoder count
EPSILON_MM = 1e-9

Point = tuple[float, float, float]


@dataclass(frozen=True)
class Move:
    """A straight segment from `start` to `end` (stage mm, X Y Z): at `feed_mm_s` along the path,
    or rapid (None: every axis at its own maximum speed, G00)."""

    start: Point
    end: Point
    feed_mm_s: float | None
    line: int

    def deltas(self) -> dict[str, float]:
        """Signed distance (mm) of each axis that moves."""
        pairs = zip(AXES, self.start, self.end, strict=True)
        return {a: e - s for a, s, e in pairs if abs(e - s) > EPSILON_MM}

    def length(self) -> float:
        return math.dist(self.start, self.end)

    def axis_speeds(self) -> dict[str, float]:
        """MS-TRACER-5: each moving axis's `S` is its component of the feed vector, so all axes
        arrive together and the tool moves along the line at the feed. Empty for a rapid."""
        if self.feed_mm_s is None:
            return {}
        length = self.length()
        return {a: self.feed_mm_s * abs(d) / length for a, d in self.deltas().items()}

    def __str__(self) -> str:
        moving = self.deltas()
        target = " ".join(f"{a}={e:.6f}" for a, e in zip(AXES, self.end, strict=True) if a in moving)
        how = "rapid" if self.feed_mm_s is None else f"at {self.feed_mm_s:.6f} mm/s"
        return f"line {self.line}: move {target} {how}"


@dataclass(frozen=True)
class Dwell:
    """G04: wait `seconds` once the previous moves have ended."""

    seconds: float
    line: int

    def __str__(self) -> str:
        return f"line {self.line}: dwell {self.seconds * 1000:g} ms"


@dataclass(frozen=True)
class Output:
    """M03 (`on`) / M05: the controller's TTL output, `TTL Y=1` / `TTL Y=0` (MS-TRACER-3)."""

    on: bool
    line: int

    def __str__(self) -> str:
        return f"line {self.line}: TTL output {'on (M03)' if self.on else 'off (M05)'}"


Step = Move | Dwell | Output


def moving_axes(steps: Iterable[Step]) -> dict[str, int]:
    """The axes a plan moves, each with the program line that first moves it."""
    first_use: dict[str, int] = {}
    for step in steps:
        if isinstance(step, Move):
            for axis in step.deltas():
                first_use.setdefault(axis, step.line)
    return first_use


def chord_count(radius_mm: float, sweep_rad: float, sagitta_mm: float = SAGITTA_MM) -> int:
    """The fewest equal chords of an arc of `radius_mm` over `abs(sweep_rad)` whose sagitta
    r·(1 − cos(θ/2)) stays within `sagitta_mm`. A chord never spans more than half a turn, where
    the sagitta stops being its largest distance from the arc."""
    sweep = abs(sweep_rad)
    if sweep <= 0:
        return 1
    widest = math.pi if sagitta_mm >= radius_mm else min(math.pi, 2 * math.acos(1 - sagitta_mm / radius_mm))
    count = max(1, math.ceil(sweep / widest))
    # rounding in acos may leave the bound a hair exceeded: one more chord settles it
    while radius_mm * (1 - math.cos(sweep / count / 2)) > sagitta_mm:
        count += 1
    return count


@dataclass(frozen=True)
class Plane:
    """G17/G18/G19: the arc plane's first and second axes (right-handed with the normal axis), as
    indices into a Point. Counter-clockwise (G03) runs from the first axis towards the second."""

    code: int
    first: int
    second: int
    normal: int


PLANES = {17: Plane(17, 0, 1, 2), 18: Plane(18, 2, 0, 1), 19: Plane(19, 1, 2, 0)}


def arc_chords(
    start: Point, end: Point, centre: tuple[float, float], plane: Plane, clockwise: bool
) -> list[Point]:
    """The chord end points of the arc from `start` to `end` about `centre` (in the plane's first and
    second coordinates), the last being `end` itself. Start equal to end (in the plane) is a full
    turn. A radius that differs between the ends changes linearly along the way, and the normal
    axis moves linearly with the angle (a helix)."""
    return list(iter_arc_chords(start, end, centre, plane, clockwise))


def iter_arc_chords(
    start: Point, end: Point, centre: tuple[float, float], plane: Plane, clockwise: bool
) -> Iterator[Point]:
    """`arc_chords` a point at a time: a huge arc's hundred thousand chords are never held at once."""
    cu, cv = centre
    u0, v0 = start[plane.first] - cu, start[plane.second] - cv
    u1, v1 = end[plane.first] - cu, end[plane.second] - cv
    r0, r1 = math.hypot(u0, v0), math.hypot(u1, v1)
    a0 = math.atan2(v0, u0)
    if math.hypot(u1 - u0, v1 - v0) <= EPSILON_MM:
        sweep = -2 * math.pi if clockwise else 2 * math.pi
    else:
        ccw = (math.atan2(v1, u1) - a0) % (2 * math.pi)
        sweep = ccw - 2 * math.pi if clockwise else ccw
    count = chord_count(max(r0, r1), sweep)
    for i in range(1, count):
        share = i / count
        angle = a0 + sweep * share
        radius = r0 + (r1 - r0) * share
        point = [0.0, 0.0, 0.0]
        point[plane.first] = cu + radius * math.cos(angle)
        point[plane.second] = cv + radius * math.sin(angle)
        point[plane.normal] = start[plane.normal] + (end[plane.normal] - start[plane.normal]) * share
        yield (point[0], point[1], point[2])
    yield end
