"""What the status readouts make of an axis (MS-79…MS-82, MS-106, MS-122): the status byte of `RS`,
`RB` and low-level frames, the right status character of `RS L+`, and INFO's `Move_stat`. The left
character needs the buttons and is the controller's (`left_char`)."""

from __future__ import annotations

from emulator.devices.ms2000.activity import LOWER, UPPER, Activity
from emulator.devices.ms2000.axis import Axis


def status_byte(axis: Axis, t: float, bit5_up_is_one: bool = True, low_level: bool = False) -> int:
    byte = 0
    if axis.busy(t):
        byte |= 1
    if axis.enabled or low_level:
        byte |= 2
    if axis.motor_on(t):
        byte |= 4
    if axis.s.manual_enabled:
        byte |= 8
    accel = axis.traj.acc(t)
    if axis.traj.moving(t) and accel != 0:
        byte |= 16
        speeding_up = accel * axis.traj.vel(t) > 0
        if speeding_up == bit5_up_is_one:
            byte |= 32
    if axis.at_limit(t, UPPER):
        byte |= 64
    if axis.at_limit(t, LOWER):
        byte |= 128
    return byte


def right_char(axis: Axis, t: float) -> str:
    if axis.paused(t):
        return "P"
    if axis.activity is Activity.MOVE:
        return "m"
    if axis.activity is Activity.HOME:
        return "B"
    if axis.activity in (Activity.SPIN, Activity.VELOCITY):
        return "s"
    if axis.activity is Activity.PATTERN:
        return "T"  # MS-MULTI-2
    return " "


def move_stat(axis: Axis, t: float) -> str:
    if axis.paused(t):
        return "PAUSE"
    if not axis.traj.moving(t):
        return "IDLE"
    accel = axis.traj.acc(t)
    if accel == 0:
        return "CRUISE"
    return "RAMP" if accel * axis.traj.vel(t) > 0 else "LAND"
