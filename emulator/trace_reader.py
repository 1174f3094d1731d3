"""Reading a traffic log that may still be growing, for `stage-emu trace` (emulator/trace.py).

`LogFollower.read_lines` returns the complete lines written since the last call. A last line without
its newline is still being written: it is held back until the rest arrives. When the path comes to
name another file (rotated away, and the daemon reopened a fresh one on SIGUSR1) or the file
shrinks (truncated in place), reading starts over at the beginning of what the path names now.
"""

from __future__ import annotations

import os
from pathlib import Path
from types import TracebackType
from typing import BinaryIO

#: bytes read at a time, so a long log is not read into memory whole
CHUNK = 1 << 20


class TraceError(Exception):
    """A log that cannot be traced; the message is one line naming the file."""


class LogFollower:
    def __init__(self, path: Path) -> None:
        self.path = path
        self._file: BinaryIO | None = None
        self._identity: tuple[int, int] = (0, 0)
        self._partial = b""

    def __enter__(self) -> LogFollower:
        self._file = self._open()
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
        return bool(self._partial)

    def _open(self) -> BinaryIO:
        try:
            if self.path.is_dir():
                raise TraceError(f"{self.path}: is a directory, not a traffic log")
            file = self.path.open("rb")
        except FileNotFoundError:
            raise TraceError(f"{self.path}: no such file") from None
        except OSError as exc:
            raise TraceError(f"{self.path}: cannot read it ({exc.strerror or exc})") from None
        status = os.fstat(file.fileno())
        self._identity = (status.st_dev, status.st_ino)
        self._partial = b""
        return file

    def read_lines(self) -> list[str]:
        """Complete lines written since the last call (without their newlines), a chunk at a time:
        none only at the end of what is written so far."""
        file = self._file
        assert file is not None, "read_lines outside `with`"
        while chunk := file.read(CHUNK):
            lines = self._take(chunk)
            if lines:
                return lines
        # at the end: does the path still name this file, as long as it was?
        try:
            status = os.stat(self.path)
        except OSError:
            return []  # between a rotation and the reopen: keep the old file until a new one appears
        if (status.st_dev, status.st_ino) != self._identity:
            file.close()  # replaced (rotated, then reopened by the daemon on SIGUSR1): the new file
            self._file = self._open()
            return self.read_lines()
        if status.st_size < file.tell():
            file.seek(0)  # truncated in place (copytruncate)
            self._partial = b""
            return self.read_lines()
        return []

    def _take(self, chunk: bytes) -> list[str]:
        if not chunk:
            return []
        *complete, self._partial = (self._partial + chunk).split(b"\n")
        return [line.decode("utf-8", errors="replace") for line in complete]
