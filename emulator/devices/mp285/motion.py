"""MP-285 motion: where the axes are, where a command sends them and how they get there (docs/mp285.md
§4, §6, §10). Pure: no replies, no clock of its own; times are passed in.

- `Stage`: physical positions, origin, travel, µsteps per µm; move and program targets after MP-42
  quantisation and MP-36 travel limits;
- `Motion`: one straight-line move, all axes together or one after another (MP-43 ... MP-46);
- `Run`: the move of an outstanding `m`, `k` or `e`, with its settle time and why it was halted
  (MP-44, MP-48, MP-51); `Program`: a program being run or paused (MP-68 ... MP-70).
"""

from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from emulator.devices.mp285.schema import Mp285Knobs, Mp285Stage
from emulator.motion import Trapezoid
from protocols import mp285 as proto
from protocols.mp285 import Vector, round_half_away

Xyz = tuple[int, int, int]
NO_MOVE: Xyz = (0, 0, 0)


def xyz(values: Iterable[int]) -> Xyz:
    x, y, z = values
    return (x, y, z)


def round_to(value: int, quantum: int) -> int:
    """Nearest multiple of `quantum`, ties away from zero, in integer arithmetic (MP-42)."""
    magnitude = (2 * abs(value) + quantum) // (2 * quantum) * quantum
    return magnitude if value >= 0 else -magnitude


@dataclass(frozen=True)
class Motion:
    """A straight-line move from `p0` by `delta` (µsteps) starting at `start`. Each axis follows its
    profile from its own offset (all 0 when the axes move together); None = speed 0, never moves."""

    start: float
    p0: Xyz
    delta: Xyz
    profiles: tuple[tuple[float, Trapezoid | None], ...]
    duration: float

    @classmethod
    def plan(
        cls,
        start: float,
        p0: Xyz,
        target: Xyz,
        factors: tuple[float, ...],
        speed: int,
        accel_um_s2: float,
        sequential: bool,
    ) -> Motion:
        delta = xyz(t - p for t, p in zip(target, p0, strict=True))
        distances = [abs(d) / f for d, f in zip(delta, factors, strict=True)]
        if not any(delta):
            return cls(start, p0, delta, ((0.0, None),) * 3, 0.0)
        if speed == 0:  # MP-40: never ends on its own
            return cls(start, p0, delta, ((0.0, None),) * 3, math.inf)
        ramp = speed / accel_um_s2 if accel_um_s2 > 0 else 0.0  # MP-45
        if sequential:  # MP-43
            profiles: list[tuple[float, Trapezoid | None]] = []
            offset = 0.0
            for distance in distances:
                profile = Trapezoid(distance, speed, ramp)
                profiles.append((offset, profile))
                offset += profile.duration
            return cls(start, p0, delta, tuple(profiles), offset)
        profile = Trapezoid(max(distances), speed, ramp)
        return cls(start, p0, delta, ((0.0, profile),) * 3, profile.duration)

    def position(self, t: float) -> Xyz:
        """MP-46: P(t) = P_start + round(ΔP · s(t)), s = share of the path covered."""
        result = []
        for p, d, (offset, profile) in zip(self.p0, self.delta, self.profiles, strict=True):
            share = 0.0 if profile is None else profile.fraction(t - self.start - offset)
            result.append(p + round_half_away(d * share) if d else p)
        return xyz(result)

    @property
    def target(self) -> Xyz:
        return xyz(p + d for p, d in zip(self.p0, self.delta, strict=True))


@dataclass
class Program:
    """A program being executed or paused: its vectors (a copy) and the next one to run."""

    number: int
    vectors: tuple[Vector, ...]
    next: int = 0


#: final reply of a move halted by a byte other than ^C, by `move_interrupt_reply` (MP-53)
INTERRUPTED_REPLIES = {
    "cr": b"\r",
    "error8": proto.error_reply(proto.ErrorCode.MOVE_INTERRUPTED),
    "error8_4": proto.error_reply(
        proto.combine_errors(proto.ErrorCode.MOVE_INTERRUPTED, proto.ErrorCode.BAD_COMMAND)
    ),
}


class Halt(enum.Enum):
    """Why a run was halted before its end (the `halted` field of the `move_ended` event)."""

    CTRL_C = "ctrl_c"  # MP-48
    BYTE = "byte"  # MP-51


@dataclass
class Run:
    """An outstanding `m`, or the current move of a program started by `k` or `e` (§7): the axes
    travel until `motion_end` (MOVING), then settle until `final_at` (STOPPING, MP-44)."""

    motion: Motion
    motion_end: float
    final_at: float
    program: Program | None = None
    cause: Halt | None = None  # None: not halted (yet)

    def moving(self, t: float) -> bool:
        return t < self.motion_end

    def position(self, t: float) -> Xyz:
        return self.motion.position(min(t, self.motion_end))

    def halt(self, t: float, settle_s: float, cause: Halt) -> None:
        """Stop the axes where they are; STOPPING lasts `settle_s` from now (MP-48, MP-51)."""
        self.motion = dataclasses.replace(self.motion, p0=self.position(t), delta=NO_MOVE)
        self.motion_end = t
        self.final_at = t + settle_s
        self.cause = cause


class Stage:
    """The three axes: physical µsteps from the bottom of travel and the origin (MP-30, MP-32), the
    travel (MP-29, MP-36) and µsteps per µm (MP-28). Reported positions are physical minus origin."""

    def __init__(self, stage: Mp285Stage, knobs: Mp285Knobs) -> None:
        self.factors = proto.axis_factors(stage.device_type, stage.z_usteps_per_um)
        self.travel = xyz(stage.travel_usteps)
        self.physical = xyz(stage.power_on_physical_usteps)
        self.origin = xyz(stage.origin_usteps_from_bot)
        self._quantum: int = knobs.coarse_step_quantum_usteps
        self._reject_outside = knobs.out_of_range == "error4"
        self._vectors_follow_mode = knobs.program_vectors == "follow_mode"
        self._accel: float = knobs.accel_um_s2
        self._sequential = knobs.axis_motion == "sequential"
        self._settle: float = knobs.settle_s

    def reported(self, physical: Xyz) -> Xyz:
        return xyz(p - o for p, o in zip(physical, self.origin, strict=True))

    def at(self, run: Run | None, t: float) -> Xyz:
        """Physical position at `t`, interpolated while `run` moves."""
        return self.physical if run is None else run.position(t)

    def move_target(self, values: Xyz, relative: bool, high_resolution: bool) -> Xyz | None:
        """The physical target of `m` (MP-33, MP-36: 64-bit arithmetic); None = reject ('4')."""
        if relative:
            raw = [p + v for p, v in zip(self.physical, values, strict=True)]
        else:
            raw = [v + o for v, o in zip(values, self.origin, strict=True)]
        return self._limit(raw, high_resolution)

    def vector_target(self, vector: Vector, relative: bool, high_resolution: bool) -> Xyz | None:
        """MP-69: displacements, or absolute targets in absolute mode with `follow_mode`."""
        if self._vectors_follow_mode and not relative:
            raw = [v + o for v, o in zip(vector.xyz, self.origin, strict=True)]
        else:
            raw = [p + v for p, v in zip(self.physical, vector.xyz, strict=True)]
        return self._limit(raw, high_resolution)

    def _limit(self, raw: list[int], high_resolution: bool) -> Xyz | None:
        """Physical targets after MP-42 quantisation and MP-36 travel limits; None = reject ('4')."""
        quantum = self._quantum
        if quantum > 1 and not high_resolution:
            raw = [p + round_to(r - p, quantum) for r, p in zip(raw, self.physical, strict=True)]
        inside = all(0 <= r <= length for r, length in zip(raw, self.travel, strict=True))
        if not inside and self._reject_outside:
            return None
        return xyz(min(max(r, 0), length) for r, length in zip(raw, self.travel, strict=True))

    def start(self, t: float, target: Xyz, speed: int, program: Program | None) -> Run:
        """A run from where the axes are to `target` at `speed` µm/s, settling `settle_s` (MP-44)."""
        motion = Motion.plan(t, self.physical, target, self.factors, speed, self._accel, self._sequential)
        end = t + motion.duration
        return Run(motion, end, end + self._settle, program)

    def turn(self, axis: int, usteps: int) -> None:
        """MP-79: the ROE moves one axis at once, clamped to travel."""
        moved = min(max(self.physical[axis] + usteps, 0), self.travel[axis])
        self.physical = xyz(moved if i == axis else p for i, p in enumerate(self.physical))

    def snapshot(self, run: Run | None, t: float) -> dict[str, Any]:
        """The position keys of the device snapshot."""
        axes = proto.AXES
        physical = self.at(run, t)
        reported = self.reported(physical)
        return {
            "position": {
                "usteps": dict(zip(axes, reported, strict=True)),
                "um": {a: round(p / f, 4) for a, p, f in zip(axes, reported, self.factors, strict=True)},
            },
            "physical_usteps": dict(zip(axes, physical, strict=True)),
            "origin_usteps_from_bot": dict(zip(axes, self.origin, strict=True)),
            "travel_usteps": dict(zip(axes, self.travel, strict=True)),
            "target_usteps": None
            if run is None
            else dict(zip(axes, self.reported(run.motion.target), strict=True)),
        }
