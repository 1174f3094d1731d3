"""Reading a traffic log that may still be growing, for `stage-emu trace` (emulator/tools/trace.py).

`LogFollower.read_lines` returns the complete lines written since the last call, a batch at a time,
through the bounded reader (emulator/tools/readers.py: a regular file only, lines of bounded length). A
last line without its newline is still being written: it is held back until the rest arrives. When
the path comes to name another file (rotated away, and the daemon reopened a fresh one on SIGUSR1)
or the file shrinks (truncated in place), reading starts over at the beginning of what the path
names now.
"""

from __future__ import annotations

import os
from pathlib import Path
from types import TracebackType
from typing import BinaryIO

from emulator.tools.readers import Line, LineReader, ReadError, open_regular

#: lines returned at most per call, so a long log is not read into memory whole
BATCH = 4096
#: what the files read here are, for the messages
WHAT = "traffic log"


class TraceError(ReadError):
    """A log that cannot be traced; the message is one line naming the file."""


class LogFollower:
    def __init__(self, path: Path) -> None:
        self.path = path
        self._file: BinaryIO | None = None
        self._reader: LineReader | None = None
        self._identity: tuple[int, int] = (0, 0)

    def __enter__(self) -> LogFollower:
        self._open()
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, trace: TracebackType | None
    ) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None

    @property
    def has_partial_line(self) -> bool:
        """The file ends in a line without its newline (held back)."""
        return self._reader is not None and bool(self._reader.held)

    def _open(self) -> None:
        file = open_regular(self.path, WHAT)
        status = os.fstat(file.fileno())
        self._identity = (status.st_dev, status.st_ino)
        self._file = file
        self._reader = LineReader(file, self.path, WHAT)

    def read_lines(self) -> list[Line]:
        """Complete lines written since the last call (at most BATCH): none only at the end of what
        is written so far."""
        file, reader = self._file, self._reader
        assert file is not None and reader is not None, "read_lines outside `with`"
        lines: list[Line] = []
        while len(lines) < BATCH and (line := reader.take()) is not None:
            lines.append(line)
        if lines:
            return lines
        # at the end: does the path still name this file, as long as it was?
        try:
            status = os.stat(self.path)
        except OSError:
            return []  # between a rotation and the reopen: keep the old file until a new one appears
        if (status.st_dev, status.st_ino) != self._identity:
            file.close()  # replaced (rotated, then reopened by the daemon on SIGUSR1): the new file
            self._file = None
            self._open()
            return self.read_lines()
        if status.st_size < file.tell():
            file.seek(0)  # truncated in place (copytruncate)
            self._reader = LineReader(file, self.path, WHAT)
            return self.read_lines()
        return []
