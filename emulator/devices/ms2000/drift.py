"""Holding position: drift correction after a disturbance, the runaway limit (MS-61, MS-62).

An axis at rest that is pushed off its target by more than `E` (the drift error) is brought back by
correction moves, one per servo period at first; outside `MA=1/2` at most `CORRECTION_ATTEMPTS`
within `CORRECTION_WINDOW_S`. A force that keeps holding the axis off (`hold`) defeats them: past
the attempts the controller logs 60 + axis. An error beyond `RU` disables the motor (30 + axis).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from emulator.devices.ms2000 import trajectory
from emulator.devices.ms2000.activity import Activity
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis
    from emulator.devices.ms2000.scheduler import Timer

#: drift-correction attempts allowed within the window (MS-61) and their spacing [choice]
CORRECTION_ATTEMPTS = 18
CORRECTION_WINDOW_S = 0.5
CORRECTION_SPACING_S = 0.025


class ServoHold:
    """One axis's position servo at rest: what a disturbance does and how it is corrected."""

    def __init__(self, axis: Axis) -> None:
        self.axis = axis
        #: an outside force keeps the axis displaced (corrections cannot win)
        self.hold = False
        self.attempts = 0
        self.window_start = -math.inf
        self.correction: Timer | None = None

    def disturb(self, t: float, um: float, hold: bool) -> None:
        axis = self.axis
        axis.sample(t)
        if um == 0:
            self.hold = False
            self.consider(t)
            return
        displacement = um / 1000 * axis.counts_per_mm
        if axis.activity in (Activity.IDLE, Activity.CORRECT) and not axis.paused(t):
            axis.cancel_timer()
            axis.activity = Activity.IDLE
            axis.rest(t, float(round_half_away(axis.pos(t) + displacement)))
            self.hold = hold
            self._check_runaway(t, abs(axis.pos(t) - axis.target))
            self.attempts = 0
            self.window_start = t
            self.consider(t)
        else:
            self._check_runaway(t, abs(displacement))

    def _active(self) -> bool:
        return self.axis.enabled and self.axis.s.maintain != 5

    def _check_runaway(self, t: float, error_counts: float) -> None:
        """Beyond RU the motor is disabled: whatever the axis was doing stops there (MS-62)."""
        axis = self.axis
        if self._active() and error_counts / axis.counts_per_mm > axis.s.runaway:
            axis.controller.disable_motor(axis, t)
            self.cancel()
            axis.controller.log_error(30 + axis.index)

    def consider(self, t: float) -> None:
        """Start correcting if the axis is off its target by more than the drift error."""
        axis = self.axis
        if not self._active() or self.correction is not None:
            return
        error_mm = abs(axis.pos(t) - axis.target) / axis.counts_per_mm
        if error_mm <= axis.s.drift_error:
            return
        unlimited = axis.s.maintain in (1, 2)
        if not unlimited and self.attempts >= CORRECTION_ATTEMPTS:
            return
        self.correction = axis.controller.at(t + axis.controller.servo_s, self._attempt)

    def _attempt(self, t: float) -> None:
        axis = self.axis
        self.correction = None
        if not self._active() or axis.activity not in (Activity.IDLE, Activity.CORRECT):
            return
        if t - self.window_start > CORRECTION_WINDOW_S and axis.s.maintain not in (1, 2):
            self.window_start = t
            self.attempts = 0
        self.attempts += 1
        if self.hold:
            if axis.s.maintain in (1, 2) or self.attempts < CORRECTION_ATTEMPTS:
                self.correction = axis.controller.at(t + CORRECTION_SPACING_S, self._attempt)
            else:
                axis.controller.log_error(60 + axis.index)
            return
        axis.sample(t)
        axis.activity = Activity.CORRECT
        goal = float(axis.target)
        axis.set_path(t, trajectory.plan(t, axis.pos(t), 0.0, goal, axis.speed_counts(), axis.accel_counts()))
        axis.schedule(axis.traj.end, lambda due: self._corrected(due, goal))

    def _corrected(self, t: float, goal: float) -> None:
        axis = self.axis
        axis.timer = None
        axis.sample(t)
        axis.rest(t, goal)
        axis.activity = Activity.IDLE

    def cancel(self) -> None:
        """Drop a correction waiting or under way (a new command takes the axis)."""
        if self.correction is not None:
            self.correction.cancel()
            self.correction = None
        if self.axis.activity is Activity.CORRECT:
            self.axis.activity = Activity.IDLE
