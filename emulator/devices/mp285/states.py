"""The MP-285's states (docs/mp285.md §0) and how `Mp285Device` (model.py) enters and leaves them.

- IDLE: at power-on, when a command is over, after reset or recovery; left by any of the below.
- COLLECTING, DISCARDING: the frame parser's, while IDLE or PAUSED: a command byte starts a frame;
  a bad byte discards until a clean CR (MP-21 ... MP-24).
- MOVING: `m`, or `k`/`e` reaching a move vector; becomes STOPPING when the axes come to rest, or
  at once when ^C or an interrupting byte halts them (MP-48, MP-51).
- STOPPING: left with the final reply (MP-44, MP-47) for IDLE or PAUSED, or for the MOVING of a
  program's next vector (MP-68).
- PAUSED: a pause vector (MP-68); left by `e`, `k`, ^C or a reset (MP-70, MP-71, MP-57).
- DEAF: `r` (MP-56); recovery within an earlier DEAF period; becomes IDLE `reset_deaf_s` later.
- POWERING_ON: `power_cycle` (MP-76); `power_on_s` later IDLE, or CRASHED after a latched crash.
- CRASHED: `crash`, or a byte in the ROE crash window (MP-77, MP-79); left by recovery (MP-78:
  IDLE, or DEAF within an earlier DEAF period) or a power cycle.
- LOCKED: a frame left incomplete for `lockup_incomplete_frame_s` (MP-80); left by a power cycle.

A power cycle ends any state; a crash any but POWERING_ON and LOCKED, where it is latched (the
controller comes up CRASHED; a locked one only shows `crashed`); a lock-up ends IDLE, PAUSED or
MOVING. An `m` sent while PAUSED runs, then the program is PAUSED again (MP-71).
"""

from __future__ import annotations

import enum

from protocols.mp285 import ParseState


class State(enum.Enum):
    """The reference's states. The device holds one of IDLE, PAUSED, MOVING, DEAF, POWERING_ON,
    CRASHED and LOCKED; `Mp285Device.state(t)` refines it with what time and the frame parser decide
    without an event: a MOVING run whose axes are at rest is STOPPING, a DEAF period that has run out
    is IDLE, and while IDLE or PAUSED a frame being parsed is COLLECTING or DISCARDING."""

    IDLE = "IDLE"
    COLLECTING = "COLLECTING"
    DISCARDING = "DISCARDING"
    MOVING = "MOVING"
    STOPPING = "STOPPING"
    PAUSED = "PAUSED"
    DEAF = "DEAF"
    POWERING_ON = "POWERING_ON"
    CRASHED = "CRASHED"
    LOCKED = "LOCKED"


#: what the frame parser's state refines IDLE and PAUSED to
FRAME_STATES = {ParseState.COLLECTING: State.COLLECTING, ParseState.DISCARDING: State.DISCARDING}
#: the stored states in which received characters reach the frame layer
LISTENING = (State.IDLE, State.MOVING, State.PAUSED)
#: where the ROE does nothing (MP-79: it acts while the controller is idle)
ROE_REFUSED = (State.MOVING, State.STOPPING, State.POWERING_ON, State.CRASHED, State.LOCKED)

#: why a byte is lost in a state that does not listen (traffic log)
DEAF_REASONS = {
    State.DEAF: "deaf after reset (MP-56)",
    State.POWERING_ON: "powering on (MP-76)",
    State.LOCKED: "locked up (MP-80)",
}


class Event(enum.IntEnum):
    """Internal events; due at the same instant, they run in this order."""

    BUSY_END = 0  # MP-7
    FINAL = 1  # MP-47
    LOCKUP = 2  # MP-80
    POWER_ON = 3  # MP-76
    RX = 4  # MP-6
    TX = 5  # MP-6
