"""Log lines that can repeat without bound (resource exhaustion, a client retrying in a loop) are
limited to one per kind per LOG_INTERVAL_S, and that line tells how many were held back since the
previous one. The daemon's loop-error handler and the network transports share this policy."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

#: at most one line per kind of repeated error or refusal in this many seconds
LOG_INTERVAL_S = 10.0


@dataclass
class LogLimiter:
    """Decides, per key, whether a repeated line is written now. `clock` is monotonic seconds
    (a test passes its own)."""

    clock: Callable[[], float] = time.monotonic
    interval: float = LOG_INTERVAL_S
    #: per key: when its last line was written, and how many were held back since
    _last: dict[str, tuple[float, int]] = field(default_factory=dict)

    def admit(self, key: str) -> int | None:
        """None: hold this one back (it is counted). Else write it now; the number is how many
        were held back since the previous line of this kind."""
        now = self.clock()
        last, held = self._last.get(key, (float("-inf"), 0))
        if now - last < self.interval:
            self._last[key] = (last, held + 1)
            return None
        self._last[key] = (now, 0)
        return held

    def settle(self, key: str) -> int:
        """The episode of `key` is over: how many were held back and never told (0 if none). The
        next one is written at once."""
        _last, held = self._last.pop(key, (0.0, 0))
        return held


def held_note(held: int, what: str = "more like it") -> str:
    """The suffix of a limited line: `` (and 12 more like it)``, or nothing."""
    return f" (and {held} {what})" if held else ""
