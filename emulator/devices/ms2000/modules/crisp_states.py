"""CRISP's state characters (MS-CRISP-1) and the `LK F=code` codes (MS-CRISP-3)."""

from __future__ import annotations

IDLE, READY, DIM = "I", "R", "D"
LOCK, IN_FOCUS, INHIBITED, ERROR = "K", "F", "N", "E"
LOGAMP_DONE, DITHER, GAIN_CAL, LOGAMP_CAL = "G", "f", "C", "H"
GAIN_STEPS = "12345"
#: focus-curve acquisition: to the start, lower half, upper half, back, ending (MS-CRISP-8)
CURVE_START, CURVE_LOW, CURVE_HIGH, CURVE_BACK, CURVE_END = "abcde"
OFFSET_RESET, OFFSET_RESET_END = "o", "l"

#: every state character: the table of MS-CRISP-1
STATES = frozenset("IRDKFNEGfCH12345ghijtBWabcdeol")
#: the lock is engaged: the loop runs in K and F, waits in N
ENGAGED = frozenset({LOCK, IN_FOCUS, INHIBITED})
#: states of a timed routine: a bare `LK` (the panel button) leaves them alone, and a routine
#: ending in "the previous state" never returns to one of them
ROUTINES = frozenset(LOGAMP_CAL + GAIN_CAL + GAIN_STEPS + "abcde" + OFFSET_RESET + OFFSET_RESET_END)

#: graceful codes of `LK F=` (MS-CRISP-3); others equal to a state character enter that state
TO_IDLE, TO_UNLOCK, TO_LOCK = 79, 85, 83  # `O`, `U`, `S`
TO_LOGAMP_CAL, TO_GAIN_CAL, TO_DITHER, TO_OFFSET_RESET, TO_CURVE = 72, 67, 102, 111, 97
GRACEFUL = frozenset(
    {TO_IDLE, TO_UNLOCK, TO_LOCK, TO_LOGAMP_CAL, TO_GAIN_CAL, TO_DITHER, TO_OFFSET_RESET, TO_CURVE}
)
#: SERVOLOCK_TTL, Tiger only (`T`, `Z`)
TIGER_ONLY = frozenset({84, 90})


def valid_code(code: float) -> bool:
    """A code `LK F=` accepts: a graceful one, or the ASCII of a state character."""
    if code != int(code) or int(code) in TIGER_ONLY:
        return False
    value = int(code)
    return value in GRACEFUL or (0 < value < 128 and chr(value) in STATES)
