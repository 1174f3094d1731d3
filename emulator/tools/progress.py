"""One updating line on stderr while a long file is read (`plot`, `replay`, `gcode`), so a command
that takes tens of seconds is not silent. Only on a terminal: piped or redirected, stderr gets
nothing from here, and the line is wiped when the work is done.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import TextIO

#: how many ticks pass between looks at the clock (keeps `tick` cheap per line)
EVERY = 1024
#: the least wall time between two redraws (seconds)
INTERVAL_S = 0.2


class Progress:
    """`tick()` once per unit of work; the line (`label: N units`) is drawn at the first `EVERY`
    ticks and then at most every `INTERVAL_S`; `done()` wipes it."""

    def __init__(
        self,
        label: str,
        unit: str = "lines",
        *,
        stream: TextIO | None = None,
        clock: Callable[[], float] = time.monotonic,
        enabled: bool = True,
    ) -> None:
        self.label = label
        self.unit = unit
        self.stream = sys.stderr if stream is None else stream
        #: `enabled` False: the command's own output shows how it goes (its lines on the terminal)
        self.enabled = enabled and self.stream.isatty()
        self.count = 0
        self._clock = clock
        self._drawn_at: float | None = None

    def tick(self, count: int = 1) -> None:
        self.count += count
        if self.enabled and self.count % EVERY < count:
            now = self._clock()
            if self._drawn_at is None or now - self._drawn_at >= INTERVAL_S:
                self._drawn_at = now
                self.stream.write(f"\r{self.label}: {self.count:,} {self.unit}\x1b[K")
                self.stream.flush()

    def done(self) -> None:
        """Wipe the line, if one was drawn (the command's own output follows on a clean line)."""
        if self._drawn_at is not None:
            self.stream.write("\r\x1b[K")
            self.stream.flush()
            self._drawn_at = None

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *_: object) -> None:
        self.done()
