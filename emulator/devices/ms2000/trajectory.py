"""One axis's path through time as constant-acceleration segments, and the move planner.

A leg started from rest is exactly emulator.motion.Trapezoid (MS-52: ramp time AC from rest to the
cruise speed S, symmetric deceleration). A leg re-planned while the axis is moving (MS-63) starts
from the current position and velocity: it decelerates first if it is heading away from the new
target or cannot stop in time, otherwise it accelerates or cruises towards it. Positions are
machine encoder counts (floats while moving), times device seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

_EPS = 1e-12


@dataclass(frozen=True)
class Segment:
    t0: float
    duration: float  # may be math.inf for open-ended constant velocity
    x0: float
    v0: float
    a: float = 0.0

    @property
    def t1(self) -> float:
        return self.t0 + self.duration

    def _dt(self, t: float) -> float:
        return min(max(t - self.t0, 0.0), self.duration)

    def pos(self, t: float) -> float:
        dt = self._dt(t)
        return self.x0 + self.v0 * dt + 0.5 * self.a * dt * dt

    def vel(self, t: float) -> float:
        return self.v0 + self.a * self._dt(t)

    @property
    def x1(self) -> float:
        return self.pos(self.t1) if math.isfinite(self.duration) else math.copysign(math.inf, self.v0)


class Trajectory:
    """Segments back to back from `start`; before the first and after the last the axis is at rest."""

    def __init__(self, start: float, x: float, segments: list[Segment] | None = None) -> None:
        self.start = start
        self.x_start = x
        self.segments = segments or []

    @classmethod
    def rest(cls, t: float, x: float) -> Trajectory:
        return cls(t, x)

    def shifted(self, delta: float) -> Trajectory:
        """The same path `delta` counts further: a change of frame, not a motion (MS-PC-2)."""
        return Trajectory(
            self.start, self.x_start + delta, [replace(s, x0=s.x0 + delta) for s in self.segments]
        )

    @property
    def end(self) -> float:
        return self.segments[-1].t1 if self.segments else self.start

    @property
    def x_end(self) -> float:
        return self.segments[-1].x1 if self.segments else self.x_start

    def _segment(self, t: float) -> Segment | None:
        for seg in self.segments:
            if t < seg.t1:
                return seg if t >= seg.t0 else None
        return None

    def pos(self, t: float) -> float:
        if not self.segments or t <= self.start:
            return self.x_start
        seg = self._segment(t)
        return seg.pos(t) if seg is not None else self.x_end

    def vel(self, t: float) -> float:
        seg = self._segment(t)
        return 0.0 if seg is None else seg.vel(t)

    def acc(self, t: float) -> float:
        seg = self._segment(t)
        return 0.0 if seg is None else seg.a

    def moving(self, t: float) -> bool:
        return self._segment(t) is not None

    def ramp_rate(self) -> float:
        """The acceleration the path's ramps use (0 without ramps): a planned move has one (MS-52)."""
        return max((abs(seg.a) for seg in self.segments), default=0.0)

    def critical_times(self, t0: float, t1: float) -> list[float]:
        """Times in (t0, t1) where the path may turn round or changes segment: between consecutive
        returned times (and t0, t1) the position is monotonic."""
        times: list[float] = []
        for seg in self.segments:
            if seg.t1 <= t0 or seg.t0 >= t1:
                continue
            if t0 < seg.t0 < t1:
                times.append(seg.t0)
            if seg.a != 0:
                turn = seg.t0 - seg.v0 / seg.a
                if seg.t0 < turn < seg.t1 and t0 < turn < t1:
                    times.append(turn)
            if t0 < seg.t1 < t1:
                times.append(seg.t1)
        return sorted(set(times))

    def first_reach(self, level: float, t_from: float) -> float | None:
        """First time >= t_from at which the position reaches `level` (None if never)."""
        for seg in self.segments:
            if seg.t1 <= t_from:
                continue
            lo = max(seg.t0, t_from)
            x_lo = seg.pos(lo)
            if abs(x_lo - level) <= _EPS:
                return lo
            hit = _solve(seg, level, lo)
            if hit is not None:
                return hit
        return None


def _solve(seg: Segment, level: float, t_from: float) -> float | None:
    # x0 + v0 dt + a/2 dt² = level, smallest dt with t0+dt in [t_from, t1]
    c = seg.x0 - level
    lo = t_from - seg.t0
    hi = seg.duration
    roots: list[float] = []
    if abs(seg.a) < _EPS:
        if abs(seg.v0) > _EPS:
            roots.append(-c / seg.v0)
    else:
        disc = seg.v0 * seg.v0 - 2 * seg.a * c
        if disc >= 0:
            sq = math.sqrt(disc)
            roots.extend(((-seg.v0 - sq) / seg.a, (-seg.v0 + sq) / seg.a))
    valid = [r for r in roots if lo - 1e-12 <= r <= hi + 1e-12]
    return seg.t0 + max(min(valid), lo) if valid else None


def plan(t: float, x0: float, v0: float, target: float, vmax: float, accel: float) -> list[Segment]:
    """Segments taking an axis at (x0, v0) at time t to rest at `target`, cruising at most at vmax
    with acceleration `accel` (math.inf: no ramps)."""
    segments: list[Segment] = []
    x, v, now = x0, v0, t
    for _ in range(4):
        distance = target - x
        if abs(distance) <= _EPS and abs(v) <= _EPS:
            break
        if math.isinf(accel):
            segments.append(Segment(now, abs(distance) / vmax, x, math.copysign(vmax, distance)))
            break
        direction = math.copysign(1.0, distance) if abs(distance) > _EPS else -math.copysign(1.0, v)
        u = v * direction  # speed towards the target
        stop = u * u / (2 * accel) if u > 0 else 0.0
        if u < -_EPS or stop > abs(distance) + 1e-9 or u > vmax + 1e-9:
            # heading away, unable to stop in time, or too fast: brake (to rest, or down to vmax)
            v_end = direction * vmax if (u > vmax and stop <= abs(distance)) else 0.0
            dur = abs(v - v_end) / accel
            a = -math.copysign(accel, v - v_end)
            seg = Segment(now, dur, x, v, a)
            segments.append(seg)
            x, v, now = seg.x1, v_end, seg.t1
            continue
        segments.extend(_towards(now, x, max(u, 0.0), abs(distance), direction, vmax, accel))
        break
    return segments


def _towards(
    t: float, x: float, u: float, d: float, direction: float, vmax: float, a: float
) -> list[Segment]:
    peak = math.sqrt(max((2 * a * d + u * u) / 2, 0.0))
    final = x + direction * d
    segments: list[Segment] = []
    if peak <= vmax:
        t_up = (peak - u) / a
        t_down = peak / a
        cruise = 0.0
    else:
        peak = vmax
        t_up = (vmax - u) / a
        t_down = vmax / a
        ramp_distance = (vmax * vmax - u * u) / (2 * a) + vmax * vmax / (2 * a)
        cruise = (d - ramp_distance) / vmax
    for dur, accel, cruising in ((t_up, a, False), (cruise, 0.0, True), (t_down, -a, False)):
        if dur <= _EPS:
            continue
        v0 = direction * (peak if cruising or accel < 0 else u)
        seg = Segment(t, dur, x, v0, direction * accel)
        segments.append(seg)
        t, x = seg.t1, seg.x1
    if segments:
        # land exactly: floating error must not leave the axis a fraction of a count short
        last = segments[-1]
        segments[-1] = Segment(last.t0, last.duration, last.x0 + (final - last.x1), last.v0, last.a)
    return segments


def constant(t: float, x: float, velocity: float) -> list[Segment]:
    """Open-ended constant velocity (spin, joystick, VE cruise)."""
    return [Segment(t, math.inf, x, velocity)] if velocity else []


def ramp_to(t: float, x: float, v0: float, v1: float, ramp_s: float) -> list[Segment]:
    """Change velocity from v0 to v1 in `ramp_s` seconds, then keep v1 (VE, MS-72)."""
    segments: list[Segment] = []
    if ramp_s > 0 and abs(v1 - v0) > _EPS:
        seg = Segment(t, ramp_s, x, v0, (v1 - v0) / ramp_s)
        segments.append(seg)
        t, x = seg.t1, seg.x1
    return segments + constant(t, x, v1)
