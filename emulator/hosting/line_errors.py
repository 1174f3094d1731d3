"""Line errors among a port's queued host input (emulator/hosting/pacing.py keeps them per port).

A serial port's UART reports characters it received with a framing or parity error
(`PortSink.line_error`). Such a character waits in the port's input pacer like any other byte, so it
takes its wire time and keeps its place among the bytes around it; `LineErrors` remembers which of
the queued bytes it is, so that the runner hands it to the model as an error
(`Device.receive_line_error`) rather than as data.
"""

from __future__ import annotations

from collections import deque

#: what is known of the host at the far end of a serial line (its `HostLine.describe`, and the
#: traffic log's note on each error character)
UNSEEN_HOST = (
    "host settings not visible on a serial line: a host at other settings gets garbage from the UART"
)


class LineErrors:
    """The error characters in one port's input queue, by position from the head of the queue."""

    def __init__(self) -> None:
        self._marks: deque[tuple[int, str]] = deque()

    def __bool__(self) -> bool:
        return bool(self._marks)

    def add(self, position: int, kind: str) -> None:
        """The byte queued at `position` (0: the head) is a character received with error `kind`."""
        self._marks.append((position, kind))

    def split(self, data: bytes) -> list[tuple[bytes, str | None]]:
        """`data`, the next bytes taken off the head of the queue, as runs of data (kind None) and
        single error characters (with their kind), in order."""
        pieces: list[tuple[bytes, str | None]] = []
        marks = self._marks
        start = 0
        while marks and marks[0][0] < len(data):
            position, kind = marks.popleft()
            if position > start:
                pieces.append((data[start:position], None))
            pieces.append((data[position : position + 1], kind))
            start = position + 1
        if start < len(data):
            pieces.append((data[start:] if start else data, None))
        if marks:
            self._marks = deque((position - len(data), kind) for position, kind in marks)
        return pieces

    def clear(self) -> None:
        self._marks.clear()
