"""One motor axis: coordinates, limits, the motion in progress and status (holding position: drift.py).

The physical position is a machine position in encoder counts (MS-49); the user position is
`polarity × counts / C − origin` mm, reported in units of 1/UM mm (MS-46). Commanded moves go
through backlash and overshoot legs (MS-57, MS-58), each a trapezoid (MS-52), land exactly on the
target count (MS-53), then wait `WT` (MS-56). Spin, VE and joystick motion run open-ended until a
limit or a new command (MS-71, MS-72, MS-83).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from emulator.devices.ms2000 import trajectory
from emulator.devices.ms2000.activity import BUSY_ACTIVITIES, LIMIT_CODES, LOWER, UPPER, Activity, MoveGroup
from emulator.devices.ms2000.drift import ServoHold
from emulator.devices.ms2000.settings import AxisAuto, AxisSettings
from emulator.devices.ms2000.trajectory import Trajectory
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis_owner import AxisOwner
    from emulator.devices.ms2000.scheduler import Timer
    from emulator.devices.ms2000.sections import Ms2000Axis


class Axis:
    def __init__(
        self,
        controller: AxisOwner[Axis],
        index: int,
        letter: str,
        cfg: Ms2000Axis,
        settings: AxisSettings,
        auto: AxisAuto,
        t: float,
    ) -> None:
        self.controller = controller
        self.index = index
        self.hw_letter = letter  # profile letter: persistence key
        self.letter = letter  # current name (Z2B may rename it at reset, MS-115)
        self.cfg = cfg
        self.s = settings
        self.auto = auto
        self.traj = Trajectory.rest(t, 0.0)
        self.origin = 0.0
        self.target = 0
        self.activity = Activity.IDLE
        self.legs: list[float] = []
        self.timer: Timer | None = None
        self.pause_until: float | None = None
        self.hold_until: float | None = None
        self.clamped: str | None = None
        self.enabled = True
        self.group: MoveGroup[Axis] | None = None
        self.velocity_cmd = 0.0
        self.switch = {UPPER: False, LOWER: False}
        self.servo = ServoHold(self)
        self.wheel_goal: float | None = None
        self.ext_min = 0.0
        self.ext_max = 0.0
        self._sample_t = t
        self.ensync_mm: float | None = None
        self.ensync_side = 0
        self.distance_mm = 0.0
        #: counts a module adds to the commanded path to give the physical position: planar
        #: correction makes Z follow the plane while `W Z` stays in plane coordinates (MS-PC-2)
        self.follow: Callable[[float], float] | None = None

    # ---- coordinates ---------------------------------------------------------------------------

    @property
    def counts_per_mm(self) -> float:
        return self.s.counts_per_mm

    def pos(self, t: float) -> float:
        return self.traj.pos(t)

    def physical(self, t: float) -> float:
        """The encoder position: the commanded path plus what a module makes follow it (MS-PC-2)."""
        return self.pos(t) + (self.follow(t) if self.follow is not None else 0.0)

    def physical_target(self, t: float) -> float:
        return self.target + (self.follow(t) if self.follow is not None else 0.0)

    def user_mm_of(self, counts: float) -> float:
        return self.s.polarity * counts / self.counts_per_mm - self.origin

    def counts_of(self, user_mm: float) -> float:
        return self.s.polarity * (user_mm + self.origin) * self.counts_per_mm

    def user_mm(self, t: float) -> float:
        return self.user_mm_of(self.pos(t))

    def units(self, t: float) -> float:
        return self.user_mm(t) * self.s.unit_multiplier

    def target_units(self) -> float:
        return self.user_mm_of(self.target) * self.s.unit_multiplier

    def counts_of_units(self, units: float) -> float:
        return self.counts_of(units / self.s.unit_multiplier)

    def machine_mm_of_user(self, user_mm: float) -> float:
        return self.s.polarity * (user_mm + self.origin)

    def user_of_machine_mm(self, machine_mm: float) -> float:
        return self.s.polarity * machine_mm - self.origin

    @property
    def max_speed(self) -> float:
        return self.cfg.max_speed_mm_s

    # ---- limits (MS-50, MS-65, MS-66, MS-87) ----------------------------------------------------

    def limit_counts(self) -> tuple[float, float]:
        lo_mm = max(self.auto.soft_lower, self.cfg.travel_mm[0])
        hi_mm = min(self.auto.soft_upper, self.cfg.travel_mm[1])
        c = self.counts_per_mm
        return math.ceil(lo_mm * c - 1e-6), math.floor(hi_mm * c + 1e-6)

    def at_limit(self, t: float, end: str) -> bool:
        if self.switch[end]:
            return True
        lo, hi = self.limit_counts()
        x = self.pos(t)
        return x >= hi - 0.5 if end == UPPER else x <= lo + 0.5

    def clamp(self, target: float, x: float) -> tuple[int, str | None]:
        lo, hi = self.limit_counts()
        goal = round_half_away(target)
        if self.switch[UPPER] and goal > x:
            return round_half_away(x), UPPER
        if self.switch[LOWER] and goal < x:
            return round_half_away(x), LOWER
        if goal > hi:
            return int(hi), UPPER
        if goal < lo:
            return int(lo), LOWER
        return goal, None

    # ---- status (MS-79, MS-81, MS-122) --------------------------------------------------------

    def paused(self, t: float) -> bool:
        return self.pause_until is not None and t < self.pause_until

    def busy(self, t: float) -> bool:
        return self.activity in BUSY_ACTIVITIES or self.paused(t)

    def motor_on(self, t: float) -> bool:
        if not self.enabled:
            return False
        holding = self.hold_until is not None and t < self.hold_until
        return self.activity is not Activity.IDLE or self.paused(t) or holding or self.s.maintain == 2

    # ---- sampling: extremes since the last move command, ENSYNC crossings (MS-95) -------------

    def sample(self, t: float) -> None:
        if t <= self._sample_t:
            return
        times = [*self.traj.critical_times(self._sample_t, t), t]
        for moment in times:
            x = self.user_mm_of(self.traj.pos(moment))
            self.ext_min = min(self.ext_min, x)
            self.ext_max = max(self.ext_max, x)
            if self.ensync_mm is not None:
                side = (x > self.ensync_mm) - (x < self.ensync_mm)
                if side and self.ensync_side and side != self.ensync_side:
                    self.controller.ensync_toggle()
                if side:
                    self.ensync_side = side
        self._sample_t = t

    def reset_extremes(self, t: float) -> None:
        self.sample(t)
        x = self.user_mm(t)
        self.ext_min = self.ext_max = x

    def set_ensync(self, t: float, position_mm: float) -> None:
        self.sample(t)
        self.ensync_mm = position_mm
        x = self.user_mm(t)
        self.ensync_side = (x > position_mm) - (x < position_mm)

    # ---- motion primitives ---------------------------------------------------------------------

    def cancel_timer(self) -> None:
        if self.timer is not None:
            self.timer.cancel()
            self.timer = None

    def schedule(self, due: float, action: Any) -> None:
        self.cancel_timer()
        self.timer = self.controller.at(due, action)

    def set_path(self, t: float, segments: list[trajectory.Segment]) -> None:
        self.traj = Trajectory(t, self.pos(t), segments)
        self.controller.path_changed(self, t)

    def rest(self, t: float, x: float) -> None:
        cut = self.traj.end > t  # stopped before the planned end (HALT, a limit): the path changed
        self.traj = Trajectory.rest(t, x)
        if cut:
            self.controller.path_changed(self, t)
        self.controller.positions_changed()  # every end of motion passes here (MS-111)

    def stop(self, t: float) -> None:
        """Stop dead where the axis is (HALT, stall, MS-76, MS-88); the target follows."""
        self.sample(t)
        self.cancel_timer()
        self.rest(t, float(round_half_away(self.pos(t))))
        self.activity = Activity.IDLE
        self.legs = []
        self.pause_until = None
        self.hold_until = None
        self.velocity_cmd = 0.0
        self.wheel_goal = None
        self.clamped = None
        self.target = round_half_away(self.pos(t))

    def move_to(self, t: float, goal: float, activity: Activity = Activity.MOVE) -> None:
        """Commanded move to machine count `goal` (MS-51, MS-57, MS-58, MS-63, MS-66, MS-67)."""
        self.sample(t)
        self.servo.cancel()
        x, v = self.pos(t), self.traj.vel(t)
        target, clamped = self.clamp(goal, x)
        self.target = target
        self.clamped = clamped
        self.pause_until = None
        self.hold_until = None
        self.velocity_cmd = 0.0
        self.wheel_goal = None
        self.activity = activity
        self.legs = self._waypoints(x, target) if activity is Activity.MOVE else [float(target)]
        self.distance_mm += abs(target - x) / self.counts_per_mm
        self._next_leg(t, v)

    def _waypoints(self, x: float, target: int) -> list[float]:
        lo, hi = self.limit_counts()
        points: list[float] = []
        start = x
        backlash = round_half_away(self.s.backlash * self.counts_per_mm)
        if backlash > 0 and target < x - 0.5:
            points.append(float(max(lo, target - backlash)))
            start = points[-1]
        overshoot = self.s.overshoot_counts
        if overshoot > 0 and abs(target - start) > 0.5:
            direction = 1 if target > start else -1
            points.append(float(min(hi, max(lo, target + direction * overshoot))))
        points.append(float(target))
        return points

    def speed_counts(self) -> float:
        return min(self.s.speed, self.max_speed) * self.counts_per_mm

    def accel_counts(self) -> float:
        return self.speed_counts() / (self.s.accel_ms / 1000)

    def _next_leg(self, t: float, v: float = 0.0) -> None:
        self._plan_leg(t, self.legs.pop(0), v, self.speed_counts(), self.accel_counts())

    def _plan_leg(self, t: float, goal: float, v: float, vmax: float, accel: float) -> None:
        self.set_path(t, trajectory.plan(t, self.pos(t), v, goal, vmax, accel))
        self.schedule(self.traj.end, lambda due: self._leg_end(due, goal))
        self.controller.record_sample(self, t)

    def brake(self, t: float) -> bool:
        """Ramp a commanded move down from its current velocity at the rate its ramps were planned
        with, to rest on the first whole count the ramp reaches (never past the move's own target);
        the move then ends there as moves end (a SCAN abort, MS-SCAN-5). False when the axis is not
        under way (idle, or landed and waiting out `WT`)."""
        if self.activity not in (Activity.MOVE, Activity.HOME) or not self.traj.moving(t):
            return False
        self.sample(t)
        x, v = self.pos(t), self.traj.vel(t)
        accel = self.traj.ramp_rate() or self.accel_counts()
        rest_at = x + math.copysign(v * v / (2 * accel), v)
        goal = math.ceil(rest_at - 1e-9) if v > 0 else math.floor(rest_at + 1e-9)
        if (self.target - x) * (goal - self.target) > 0:  # the target comes first on the way
            goal = self.target
        self.target = goal
        self.clamped = None
        self.legs = []
        # no faster than now: the last fraction of a count to the whole one is cruised, not sped up
        self._plan_leg(t, float(goal), v, abs(v) or self.speed_counts(), accel)
        return True

    def _leg_end(self, t: float, goal: float) -> None:
        self.timer = None
        self.sample(t)
        self.rest(t, goal)
        self.controller.record_sample(self, t)
        if self.legs:
            self._next_leg(t)
        else:
            self._landed(t)

    def _landed(self, t: float) -> None:
        if self.clamped is not None:
            self.controller.log_error(LIMIT_CODES[self.clamped])
            self.clamped = None
        settle = self.controller.knobs.landing_ms / 1000
        wait = self.s.wait_ms / 1000
        if self.activity is Activity.MOVE and self.s.maintain == 3:
            # MA=3: busy clears at landing, the servo stays on for the wait time (MS-61)
            self.hold_until = t + settle + wait
            self._finish(t)
        elif settle + wait > 0:
            self.pause_until = t + settle + wait
            self.schedule(self.pause_until, self._pause_end)
        else:
            self._finish(t)

    def _pause_end(self, t: float) -> None:
        self.timer = None
        self.pause_until = None
        self._finish(t)

    def _finish(self, t: float) -> None:
        activity = self.activity
        self.activity = Activity.IDLE
        if activity in (Activity.MOVE, Activity.HOME):
            self.controller.axis_finished(self, t)
        self.controller.resume_manual(self, t)

    # ---- open-ended motion: spin, VE, joystick -------------------------------------------------

    def spin(self, t: float, velocity_mm_s: float) -> None:
        """Open-loop drive at a constant velocity, no ramp (MS-71)."""
        self._open_ended(t, velocity_mm_s, Activity.SPIN, ramp_s=0.0)

    def vector(self, t: float, velocity_mm_s: float) -> None:
        """Ramp to a constant velocity over AC (MS-72)."""
        self.velocity_cmd = velocity_mm_s
        self._open_ended(t, velocity_mm_s, Activity.VELOCITY, ramp_s=self.s.accel_ms / 1000)

    def manual(self, t: float, velocity_mm_s: float) -> None:
        """Joystick motion: velocity follows the deflection without a ramp (MS-83)."""
        if self.activity not in (Activity.IDLE, Activity.MANUAL) or not self.enabled:
            return
        if velocity_mm_s == 0:
            if self.activity is Activity.MANUAL and self.wheel_goal is None:
                self.stop(t)
            return
        self.wheel_goal = None
        self._open_ended(t, velocity_mm_s, Activity.MANUAL, ramp_s=0.0)

    def _open_ended(self, t: float, velocity_mm_s: float, activity: Activity, ramp_s: float) -> None:
        self.sample(t)
        self.servo.cancel()
        self.cancel_timer()
        self.pause_until = None
        self.legs = []
        x, v0 = self.pos(t), self.traj.vel(t)
        velocity = velocity_mm_s * self.counts_per_mm
        if velocity == 0 and (ramp_s == 0 or v0 == 0):
            self.rest(t, float(round_half_away(x)))
            self.activity = Activity.IDLE
            self.target = round_half_away(x)
            return
        self.activity = activity
        self.set_path(t, trajectory.ramp_to(t, x, v0, velocity, ramp_s))
        if velocity == 0:
            self.schedule(self.traj.end, self._ramped_down)
            return
        end = UPPER if velocity > 0 else LOWER
        if self.at_limit(t, end):
            self._limit_stop(t, end)
            return
        lo, hi = self.limit_counts()
        hit = self.traj.first_reach(hi if end == UPPER else lo, t)
        if hit is not None:
            self.schedule(hit, lambda due: self._limit_stop(due, end))

    def _ramped_down(self, t: float) -> None:
        self.timer = None
        self.sample(t)
        x = self.traj.pos(t)
        self.rest(t, float(round_half_away(x)))
        self.target = round_half_away(x)
        self.activity = Activity.IDLE
        self.controller.resume_manual(self, t)

    def _limit_stop(self, t: float, end: str) -> None:
        self.timer = None
        activity = self.activity
        self.sample(t)
        lo, hi = self.limit_counts()
        x = self.pos(t)
        if not self.switch[end]:
            x = float(hi if end == UPPER else lo)
        self.rest(t, float(round_half_away(x)))
        self.target = round_half_away(x)
        self.activity = Activity.IDLE
        self.velocity_cmd = 0.0
        if activity in (Activity.SPIN, Activity.VELOCITY):
            self.controller.log_error(LIMIT_CODES[end])

    def nudge(self, t: float, delta_counts: float) -> None:
        """Wheel motion: a relative move that is not busy (MS-84)."""
        if self.activity not in (Activity.IDLE, Activity.MANUAL) or not self.enabled:
            return
        self.sample(t)
        self.servo.cancel()
        base = self.wheel_goal if self.wheel_goal is not None else self.pos(t)
        goal, _ = self.clamp(base + delta_counts, self.pos(t))
        self.wheel_goal = float(goal)
        self.activity = Activity.MANUAL
        v = self.traj.vel(t)
        self.set_path(t, trajectory.plan(t, self.pos(t), v, goal, self.speed_counts(), self.accel_counts()))
        self.schedule(self.traj.end, self._nudged)

    def _nudged(self, t: float) -> None:
        self.timer = None
        self.sample(t)
        goal = self.wheel_goal if self.wheel_goal is not None else self.pos(t)
        self.rest(t, goal)
        self.wheel_goal = None
        self.target = round_half_away(goal)
        self.activity = Activity.IDLE
        self.controller.resume_manual(self, t)

    # ---- disturbances, runaway, dead axis (MS-61, MS-62, MS-88) --------------------------------

    def disturb(self, t: float, um: float, hold: bool) -> None:
        """An outside force displaces the axis by `um` (held there while `hold`), see drift.py."""
        self.servo.disturb(t, um, hold)

    def stall(self, t: float) -> bool:
        """Stop a moving axis dead and log AXIS DEAD (MS-88); False when it was not moving."""
        if not self.traj.moving(t) and self.activity is Activity.IDLE:
            return False
        self.stop(t)
        self.controller.log_error(20 + self.index)
        return True

    # ---- module-driven motion: frames and paths (MS-PC-2, MS-MULTI-1) --------------------------

    def reframe(self, t: float, delta: float) -> None:
        """Re-express the commanded frame `delta` counts further (planar correction switched on or
        off, its plane re-referenced): position, target and a move in progress shift together, so
        the physical path does not jump (MS-PC-2)."""
        self.sample(t)
        moving = self.traj.moving(t)
        self.traj = self.traj.shifted(delta)
        self.target = round_half_away(self.target + delta)
        self.legs = [goal + delta for goal in self.legs]
        shift_mm = self.s.polarity * delta / self.counts_per_mm
        self.ext_min += shift_mm
        self.ext_max += shift_mm
        if self.activity is Activity.CORRECT:
            # the correction under way aims at the old frame: give it up, reconsider in the new one
            self.cancel_timer()
            self.servo.cancel()
            self.rest(t, self.pos(t))
            self.servo.consider(t)
        elif self.wheel_goal is not None:
            self.wheel_goal += delta
            self.nudge(t, 0.0)
        elif moving and self.activity in (Activity.MOVE, Activity.HOME):
            # a leg's end lands on the goal it was planned with: plan again to the shifted target
            self.move_to(t, self.target, self.activity)

    def run_path(self, t: float, segments: list[trajectory.Segment]) -> None:
        """Follow a module's path from the current position (MULTIAXIS MOVES): busy as a pattern
        until `end_path`; the module appends the next stretch before this one runs out."""
        self.sample(t)
        self.servo.cancel()
        self.cancel_timer()
        self.pause_until = None
        self.hold_until = None
        self.legs = []
        self.wheel_goal = None
        self.velocity_cmd = 0.0
        self.activity = Activity.PATTERN
        self.set_path(t, segments)
        self.target = round_half_away(self.traj.x_end)

    def end_path(self, t: float) -> None:
        """The pattern is over: the axis rests where it is and manual input may take it again."""
        self.stop(t)
        self.controller.resume_manual(self, t)

    def power_off(self, t: float) -> None:
        """Motion stops and every timer of the axis is dropped."""
        self.stop(t)
        self.servo.cancel()
        self.servo.hold = False
