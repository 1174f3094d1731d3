"""One motor axis: coordinates, limits, the motion in progress, drift correction and status.

The physical position is a machine position in encoder counts (MS-49); the user position is
`polarity × counts / C − origin` mm, reported in units of 1/UM mm (MS-46). Commanded moves go
through backlash and overshoot legs (MS-57, MS-58), each a trapezoid (MS-52), land exactly on the
target count (MS-53), then wait `WT` (MS-56). Spin, VE and joystick motion run open-ended until a
limit or a new command (MS-71, MS-72, MS-83).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from emulator.devices.ms2000 import trajectory
from emulator.devices.ms2000.activity import BUSY_ACTIVITIES, LIMIT_CODES, LOWER, UPPER, Activity
from emulator.devices.ms2000.settings import AxisAuto, AxisSettings
from emulator.devices.ms2000.trajectory import Trajectory
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.model import MoveGroup
    from emulator.devices.ms2000.modules.host import AxisHost
    from emulator.devices.ms2000.scheduler import Timer
    from emulator.devices.ms2000.schema import Ms2000Axis

#: drift-correction attempts allowed within the window (MS-61) and their spacing [choice]
CORRECTION_ATTEMPTS = 18
CORRECTION_WINDOW_S = 0.5
CORRECTION_SPACING_S = 0.025


class Axis:
    def __init__(
        self,
        host: AxisHost,
        index: int,
        letter: str,
        cfg: Ms2000Axis,
        settings: AxisSettings,
        auto: AxisAuto,
        t: float,
    ) -> None:
        self.host = host
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
        self.group: MoveGroup | None = None
        self.velocity_cmd = 0.0
        self.switch = {UPPER: False, LOWER: False}
        self.hold = False
        self.attempts = 0
        self.window_start = -math.inf
        self.correction: Timer | None = None
        self.wheel_goal: float | None = None
        self.ext_min = 0.0
        self.ext_max = 0.0
        self._sample_t = t
        self.ensync_mm: float | None = None
        self.ensync_side = 0
        self.distance_mm = 0.0

    # ---- coordinates ---------------------------------------------------------------------------

    @property
    def counts_per_mm(self) -> float:
        return self.s.counts_per_mm

    def pos(self, t: float) -> float:
        return self.traj.pos(t)

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
                    self.host.ensync_toggle()
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

    def _cancel_timer(self) -> None:
        if self.timer is not None:
            self.timer.cancel()
            self.timer = None

    def _schedule(self, due: float, action: Any) -> None:
        self._cancel_timer()
        self.timer = self.host.at(due, action)

    def _set_path(self, t: float, segments: list[trajectory.Segment]) -> None:
        self.traj = Trajectory(t, self.pos(t), segments)

    def _rest(self, t: float, x: float) -> None:
        self.traj = Trajectory.rest(t, x)
        self.host.positions_changed()  # every end of motion passes here (MS-111)

    def stop(self, t: float) -> None:
        """Stop dead where the axis is (HALT, stall, MS-76, MS-88); the target follows."""
        self.sample(t)
        self._cancel_timer()
        self._rest(t, float(round_half_away(self.pos(t))))
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
        self._cancel_correction()
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

    def _speed_counts(self) -> float:
        return min(self.s.speed, self.max_speed) * self.counts_per_mm

    def _accel_counts(self) -> float:
        return self._speed_counts() / (self.s.accel_ms / 1000)

    def _next_leg(self, t: float, v: float = 0.0) -> None:
        goal = self.legs.pop(0)
        self._set_path(
            t, trajectory.plan(t, self.pos(t), v, goal, self._speed_counts(), self._accel_counts())
        )
        self._schedule(self.traj.end, lambda due, goal=goal: self._leg_end(due, goal))
        self.host.record_sample(self, t)

    def _leg_end(self, t: float, goal: float) -> None:
        self.timer = None
        self.sample(t)
        self._rest(t, goal)
        self.host.record_sample(self, t)
        if self.legs:
            self._next_leg(t)
        else:
            self._landed(t)

    def _landed(self, t: float) -> None:
        if self.clamped is not None:
            self.host.log_error(LIMIT_CODES[self.clamped])
            self.clamped = None
        settle = self.host.knobs.landing_ms / 1000
        wait = self.s.wait_ms / 1000
        if self.activity is Activity.MOVE and self.s.maintain == 3:
            # MA=3: busy clears at landing, the servo stays on for the wait time (MS-61)
            self.hold_until = t + settle + wait
            self._finish(t)
        elif settle + wait > 0:
            self.pause_until = t + settle + wait
            self._schedule(self.pause_until, self._pause_end)
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
            self.host.axis_finished(self, t)
        self.host.resume_manual(self, t)

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
        self._cancel_correction()
        self._cancel_timer()
        self.pause_until = None
        self.legs = []
        x, v0 = self.pos(t), self.traj.vel(t)
        velocity = velocity_mm_s * self.counts_per_mm
        if velocity == 0 and (ramp_s == 0 or v0 == 0):
            self._rest(t, float(round_half_away(x)))
            self.activity = Activity.IDLE
            self.target = round_half_away(x)
            return
        self.activity = activity
        self._set_path(t, trajectory.ramp_to(t, x, v0, velocity, ramp_s))
        if velocity == 0:
            self._schedule(self.traj.end, self._ramped_down)
            return
        end = UPPER if velocity > 0 else LOWER
        if self.at_limit(t, end):
            self._limit_stop(t, end)
            return
        lo, hi = self.limit_counts()
        hit = self.traj.first_reach(hi if end == UPPER else lo, t)
        if hit is not None:
            self._schedule(hit, lambda due: self._limit_stop(due, end))

    def _ramped_down(self, t: float) -> None:
        self.timer = None
        self.sample(t)
        x = self.traj.pos(t)
        self._rest(t, float(round_half_away(x)))
        self.target = round_half_away(x)
        self.activity = Activity.IDLE
        self.host.resume_manual(self, t)

    def _limit_stop(self, t: float, end: str) -> None:
        self.timer = None
        activity = self.activity
        self.sample(t)
        lo, hi = self.limit_counts()
        x = self.pos(t)
        if not self.switch[end]:
            x = float(hi if end == UPPER else lo)
        self._rest(t, float(round_half_away(x)))
        self.target = round_half_away(x)
        self.activity = Activity.IDLE
        self.velocity_cmd = 0.0
        if activity in (Activity.SPIN, Activity.VELOCITY):
            self.host.log_error(LIMIT_CODES[end])

    def nudge(self, t: float, delta_counts: float) -> None:
        """Wheel motion: a relative move that is not busy (MS-84)."""
        if self.activity not in (Activity.IDLE, Activity.MANUAL) or not self.enabled:
            return
        self.sample(t)
        self._cancel_correction()
        base = self.wheel_goal if self.wheel_goal is not None else self.pos(t)
        goal, _ = self.clamp(base + delta_counts, self.pos(t))
        self.wheel_goal = float(goal)
        self.activity = Activity.MANUAL
        v = self.traj.vel(t)
        self._set_path(
            t, trajectory.plan(t, self.pos(t), v, goal, self._speed_counts(), self._accel_counts())
        )
        self._schedule(self.traj.end, self._nudged)

    def _nudged(self, t: float) -> None:
        self.timer = None
        self.sample(t)
        goal = self.wheel_goal if self.wheel_goal is not None else self.pos(t)
        self._rest(t, goal)
        self.wheel_goal = None
        self.target = round_half_away(goal)
        self.activity = Activity.IDLE
        self.host.resume_manual(self, t)

    # ---- disturbances, drift correction, runaway (MS-61, MS-62, MS-88) ------------------------

    def disturb(self, t: float, um: float, hold: bool) -> None:
        self.sample(t)
        if um == 0:
            self.hold = False
            self._consider_correction(t)
            return
        displacement = um / 1000 * self.counts_per_mm
        if self.activity in (Activity.IDLE, Activity.CORRECT) and not self.paused(t):
            self._cancel_timer()
            self.activity = Activity.IDLE
            self._rest(t, float(round_half_away(self.pos(t) + displacement)))
            self.hold = hold
            self._check_runaway(t, abs(self.pos(t) - self.target))
            self.attempts = 0
            self.window_start = t
            self._consider_correction(t)
        else:
            self._check_runaway(t, abs(displacement))

    def _servo_active(self) -> bool:
        return self.enabled and self.s.maintain != 5

    def _check_runaway(self, t: float, error_counts: float) -> None:
        """Beyond RU the motor is disabled: whatever the axis was doing stops there (MS-62)."""
        if self._servo_active() and error_counts / self.counts_per_mm > self.s.runaway:
            self.host.disable_motor(self, t)
            self._cancel_correction()
            self.host.log_error(30 + self.index)

    def _consider_correction(self, t: float) -> None:
        if not self._servo_active() or self.correction is not None:
            return
        error_mm = abs(self.pos(t) - self.target) / self.counts_per_mm
        if error_mm <= self.s.drift_error:
            return
        unlimited = self.s.maintain in (1, 2)
        if not unlimited and self.attempts >= CORRECTION_ATTEMPTS:
            return
        self.correction = self.host.at(t + self.host.servo_s, self._attempt)

    def _attempt(self, t: float) -> None:
        self.correction = None
        if not self._servo_active() or self.activity not in (Activity.IDLE, Activity.CORRECT):
            return
        if t - self.window_start > CORRECTION_WINDOW_S and self.s.maintain not in (1, 2):
            self.window_start = t
            self.attempts = 0
        self.attempts += 1
        if self.hold:
            if self.s.maintain in (1, 2) or self.attempts < CORRECTION_ATTEMPTS:
                self.correction = self.host.at(t + CORRECTION_SPACING_S, self._attempt)
            else:
                self.host.log_error(60 + self.index)
            return
        self.sample(t)
        self.activity = Activity.CORRECT
        goal = float(self.target)
        self._set_path(
            t, trajectory.plan(t, self.pos(t), 0.0, goal, self._speed_counts(), self._accel_counts())
        )
        self._schedule(self.traj.end, lambda due: self._corrected(due, goal))

    def _corrected(self, t: float, goal: float) -> None:
        self.timer = None
        self.sample(t)
        self._rest(t, goal)
        self.activity = Activity.IDLE

    def _cancel_correction(self) -> None:
        if self.correction is not None:
            self.correction.cancel()
            self.correction = None
        if self.activity is Activity.CORRECT:
            self.activity = Activity.IDLE

    def stall(self, t: float) -> bool:
        """Stop a moving axis dead and log AXIS DEAD (MS-88); False when it was not moving."""
        if not self.traj.moving(t) and self.activity is Activity.IDLE:
            return False
        self.stop(t)
        self.host.log_error(20 + self.index)
        return True

    def power_off(self, t: float) -> None:
        """Motion stops and every timer of the axis is dropped."""
        self.stop(t)
        self._cancel_correction()
        self.hold = False
