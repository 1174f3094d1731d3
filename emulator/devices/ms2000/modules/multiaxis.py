"""MULTIAXIS MOVES: circles, helices and spirals run by the controller (§9.13, MS-MULTI-1, MS-MULTI-2).

`MM X=radius Y=speed Z=width F=mode` sets the parameters (saved with `SS Z`); `MM` alone starts
the pattern from the current position. Mode bits: 0 lead-in (the current position is the centre
and X first moves out to the radius; otherwise the current position is on the circle at angle 0),
1 speed ramps over `AC`, 2 repeat until stopped, 7–6 the pattern (00 fast circles, 01 circle, 10
helix: Z rises by the width per turn, 11 spiral: the radius grows by the width per turn up to the
radius, from the current position as centre). `MM R=80` stops (ramping down along the path), `MM
R=82` restarts fast circles; `MM R?` reads the state's character code (`I` 73 idle, `L` 76
lead-in, `C` 67 running, `P` 80 stopping).

The pattern runs in the motion model: every 64 steps of the path (multiaxis_path.py) become the
axes' next stretch of trajectory, appended on the device clock as the last one ends, so positions
can be read anywhere along the way. The axes are busy meanwhile (right status character `T`), and
`M`/`R` naming them are refused with `:N-5`; another motion command, HALT, a stall or a limit
ends the pattern.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from emulator.devices.ms2000 import trajectory
from emulator.devices.ms2000.activity import LIMIT_CODES, LOWER, UPPER, Activity
from emulator.devices.ms2000.calls import Call, CommandError, Param, Reply, run_settings, within
from emulator.devices.ms2000.modules import Handler, Module, register
from emulator.devices.ms2000.modules.capabilities import CommandVeto, ControlChannel, LcdSegment
from emulator.devices.ms2000.modules.events import Halt, Reset, on
from emulator.devices.ms2000.modules.multiaxis_path import (
    TAU,
    Geometry,
    PathMotion,
    Pattern,
    Sample,
    segments,
)
from protocols.ms2000 import ErrorCode, Fmt, Kind

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis
    from emulator.devices.ms2000.modules.owner import ModuleOwner
    from emulator.devices.ms2000.scheduler import Timer
    from emulator.devices.ms2000.trajectory import Segment

IDLE, LEAD_IN, RUNNING, STOPPING = "I", "L", "C", "P"
#: `MM R=` codes a host may set (MS-MULTI-2)
STOP, RESTART = ord("P"), ord("R")
LEAD_IN_BIT, RAMP_BIT, REPEAT_BIT = 1, 2, 4
PATTERN_SHIFT = 6
#: largest radius and width (mm) and speed (mm/s) accepted, as the profile's bounds [choice]
MAX_DISTANCE_MM, MAX_SPEED_MM_S = 10_000.0, 1000.0
#: path steps per stretch of trajectory handed to the axes
CHUNK_STEPS = 64
#: parameters start as the firmware's zeroed variables [choice]: `MM` alone needs them set
FACTORY: dict[str, float] = {"X": 0.0, "Y": 0.0, "Z": 0.0, "F": 0}


@register
class MultiaxisMoves(Module, CommandVeto, LcdSegment, ControlChannel):
    name = "MULTIAXIS MOVES"
    observable = "multi"

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.params = dict(FACTORY)
        self.state = IDLE
        self.motion: PathMotion | None = None
        #: the pattern's axes with their coordinate in the path (0 X, 1 Y, 2 Z)
        self.axes: list[tuple[Axis, int]] = []
        #: the path steps of the stretch the axes are following now
        self.samples: list[Sample] = []
        self._timer: Timer | None = None

    @property
    def mode(self) -> int:
        return int(self.params["F"])

    @property
    def pattern(self) -> Pattern:
        return Pattern((self.mode >> PATTERN_SHIFT) & 3)

    # ---- the command --------------------------------------------------------------------------

    def handlers(self) -> dict[str, Handler]:
        return {"MM": self.mm}

    def mm(self, call: Call) -> Reply:
        """MULTIMV (MS-MULTI-1, MS-MULTI-2)."""
        controller = self.controller
        now = call.now
        if not [i for i in call.items if i.kind is not Kind.NUMBER]:
            self.start(now)
            return controller.ack()

        def setter(letter: str) -> Any:
            return lambda value: self.params.__setitem__(letter, value)

        def fixed(letter: str, high: float) -> Param:
            return Param(lambda: self.params[letter], setter(letter), within(0.0, high), Fmt.F6)

        params = {
            "X": fixed("X", MAX_DISTANCE_MM),
            "Y": fixed("Y", MAX_SPEED_MM_S),
            "Z": fixed("Z", MAX_DISTANCE_MM),
            "F": Param(lambda: self.params["F"], setter("F"), within(0, 255, integer=True)),
            "R": Param(
                lambda: ord(self.state), lambda code: self._set_code(code, now), self._check_code, Fmt.F6
            ),
        }
        saved = dict(self.params)
        try:
            return run_settings(call, params, "XYZFR", controller.render(call.key), controller.ack())
        except CommandError:
            self.params = saved  # `R=82` failing to start leaves the letters set before it unset
            raise

    def _check_code(self, code: float) -> float:
        """Only stop, and restart of fast circles, may be set (MS-MULTI-2; others :N-4 [choice])."""
        if code == STOP or (code == RESTART and self.pattern is Pattern.FAST_CIRCLES):
            return code
        raise CommandError(ErrorCode.OUT_OF_RANGE)

    def _set_code(self, code: float, now: float) -> None:
        if code == STOP:
            self.stop(now)
        elif self.state == IDLE:
            self.start(now)
        elif self.motion is not None and self.mode & REPEAT_BIT == 0:
            self.motion.end_theta = self.motion.now.theta + TAU  # one more whole circle from here

    def refuse(self, call: Call) -> int | None:
        """While a pattern runs, `M` and `R` of its axes fail (MS-MULTI-2)."""
        if self.state == IDLE or call.key not in ("M", "R"):
            return None
        mine = {axis.letter for axis, _ in self.axes}
        return ErrorCode.FAILED if mine.intersection(call.letters()) else None

    # ---- starting ------------------------------------------------------------------------------

    def start(self, now: float) -> None:
        """Start the pattern from the current position; `:N-5` when running, when an axis it needs
        is missing or busy, or without a radius and speed (a spiral also needs a width) [choice]."""
        by_letter = {a.hw_letter: a for a in self.controller.axes}
        x, y, z = (by_letter.get(letter) for letter in "XYZ")
        radius, speed, width = self.params["X"], self.params["Y"], self.params["Z"]
        pattern = self.pattern
        helix = pattern is Pattern.HELIX
        if (
            self.state != IDLE
            or x is None
            or y is None
            or (helix and z is None)
            or radius <= 0
            or speed <= 0
            or (pattern is Pattern.SPIRAL and width <= 0)
        ):
            raise CommandError(ErrorCode.FAILED)
        axes = [(x, 0), (y, 1)] + ([(z, 2)] if helix and z is not None else [])
        if any(axis.busy(now) or not axis.enabled for axis, _ in axes):
            raise CommandError(ErrorCode.FAILED)
        self.axes = axes
        speed = min(speed, x.max_speed, y.max_speed)
        accel = speed / (x.s.accel_ms / 1000)
        centre_x, centre_y = x.pos(now) / x.counts_per_mm, y.pos(now) / y.counts_per_mm
        lead_in = bool(self.mode & LEAD_IN_BIT) and pattern is not Pattern.SPIRAL
        if not lead_in and pattern is not Pattern.SPIRAL:
            centre_x -= radius  # here is the circle's point at angle 0
        z0 = z.pos(now) / z.counts_per_mm if z is not None else 0.0
        geometry = Geometry(pattern, centre_x, centre_y, z0, radius, width)
        ramped = bool(self.mode & RAMP_BIT)
        self.motion = PathMotion(
            geometry,
            speed,
            accel if ramped else None,
            accel,
            math.inf if self.mode & REPEAT_BIT else geometry.cycle_angle(),
            Sample(now, 0.0, 0.0 if ramped else speed),
        )
        if lead_in:
            self._lead_in(now)
        else:
            self._begin(now)

    def _lead_in(self, now: float) -> None:
        """From the centre straight out along +X to the circle's point at angle 0 (state L)."""
        motion = self.motion
        assert motion is not None
        self.state = LEAD_IN
        goal = motion.geometry.point(0.0)[0]
        self._run_straight(now, goal, motion.speed, motion.stop_accel, self._begin)

    def _run_straight(self, now: float, goal_mm: float, speed: float, accel: float, then: Any) -> None:
        """X moves to `goal_mm` (machine) from where it is at its velocity now; the others hold.
        A goal beyond X's limits stops at the limit, logs it and ends the pattern [choice]."""
        x = self.axes[0][0]
        c = x.counts_per_mm
        low, high = x.limit_counts()
        goal = min(max(goal_mm * c, low), high)
        if goal != goal_mm * c:
            self.controller.log_error(LIMIT_CODES[UPPER if goal == high else LOWER])
            then = self._finish
        legs = trajectory.plan(now, x.pos(now), x.traj.vel(now), goal, speed * c, accel * c)
        for axis, _ in self.axes:
            axis.run_path(now, legs if axis is x else [])
        self._schedule(legs[-1].t1 if legs else now, then)

    def _begin(self, now: float) -> None:
        motion = self.motion
        assert motion is not None
        self.state = RUNNING
        motion.now = Sample(now, motion.now.theta, motion.now.speed)
        self._advance(now, {})

    # ---- running -------------------------------------------------------------------------------

    def _schedule(self, due: float, action: Any) -> None:
        self._cancel()
        self._timer = self.controller.at(due, action)

    def _cancel(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None

    def _advance(self, now: float, kept: dict[Axis, list[Segment]]) -> None:
        """Hand the axes the next stretch of the path (after `kept`, what they still follow)."""
        motion = self.motion
        assert motion is not None
        samples = [motion.now]
        while len(samples) <= CHUNK_STEPS and not motion.finished:
            samples.append(motion.step(self.controller.servo_s))
        samples = self._within_limits(samples)
        self.samples = samples
        for axis, coordinate in self.axes:
            path = kept.get(axis, []) + segments(motion, samples, coordinate, axis.counts_per_mm)
            axis.run_path(now, path)
        self._schedule(samples[-1].t, self._stretch_end)

    def _within_limits(self, samples: list[Sample]) -> list[Sample]:
        """The samples up to the first one beyond an axis's limits: the pattern ends there and the
        limit is logged, as for a commanded move stopped by a limit [choice]."""
        motion = self.motion
        assert motion is not None
        for n, sample in enumerate(samples):
            point = motion.geometry.point(sample.theta)
            for axis, coordinate in self.axes:
                low, high = axis.limit_counts()
                counts = point[coordinate] * axis.counts_per_mm
                if not low <= counts <= high:
                    self.controller.log_error(LIMIT_CODES[UPPER if counts > high else LOWER])
                    motion.finished = True
                    return samples[: max(n, 1)]
        return samples

    def _stretch_end(self, now: float) -> None:
        self._timer = None
        motion = self.motion
        taken = any(axis.activity is not Activity.PATTERN for axis, _ in self.axes)
        if motion is None or motion.finished or taken:
            self._finish(now)
        else:
            self._advance(now, {})

    def _finish(self, now: float) -> None:
        self._cancel()
        for axis, _ in self.axes:
            if axis.activity is Activity.PATTERN:
                axis.end_path(now)
        self.state = IDLE
        self.motion = None
        self.samples = []

    def stop(self, now: float) -> None:
        """`MM R=80`: ramp down along the path over `AC`, then idle (state P meanwhile)."""
        motion = self.motion
        if motion is None or self.state in (IDLE, STOPPING):
            return
        if self.state == LEAD_IN:
            x = self.axes[0][0]
            v = x.traj.vel(now) / x.counts_per_mm
            stop_at = x.pos(now) / x.counts_per_mm + v * abs(v) / (2 * motion.stop_accel)
            self.state = STOPPING
            self._run_straight(now, stop_at, max(abs(v), 1e-9), motion.stop_accel, self._finish)
            return
        self.state = STOPPING
        # the stretch under way is kept up to its next step, where the ramp down starts
        index = next((n for n, s in enumerate(self.samples) if s.t >= now), len(self.samples) - 1)
        kept_samples = self.samples[: index + 1]
        kept = {
            axis: segments(motion, kept_samples, coordinate, axis.counts_per_mm)
            for axis, coordinate in self.axes
        }
        motion.now = kept_samples[-1]
        motion.stopping = True
        motion.finished = False
        self._advance(now, kept)

    @on(Halt)
    def halt(self, event: Halt) -> None:
        now = event.t
        self._finish(now)

    @on(Reset)
    def reset(self, event: Reset) -> None:
        now = event.t
        self._finish(now)

    # ---- reports and SS Z ----------------------------------------------------------------------

    def lcd_segment(self, now: float) -> str | None:
        return f"MM {self.state}"  # §9.0 [choice]

    def observe(self, now: float) -> Any:
        return {
            "state": self.state,
            "code": ord(self.state),
            "pattern": self.pattern.name.lower(),
            "turns": self._turns(now),
            "params": dict(self.params),
        }

    def _turns(self, now: float) -> float:
        """How far along the path the stage is, in turns (to the last step passed)."""
        passed = [s.theta for s in self.samples if s.t <= now]
        return passed[-1] / TAU if passed else 0.0

    def save(self) -> dict[str, Any]:
        return dict(self.params)

    def restore(self, data: dict[str, Any] | None) -> None:
        self.params = dict(FACTORY)
        for key, value in (data or {}).items():
            if key in self.params and isinstance(value, int | float) and not isinstance(value, bool):
                self.params[key] = value
