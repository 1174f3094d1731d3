"""Reading the files the offline commands take (`trace`, `plot`, `replay`, `gcode`), within bounds.

Every such file is read a line at a time, never whole, so memory does not grow with its length:

- `open_regular` opens only a regular file. A FIFO, a device (`/dev/zero`), a socket or a directory
  is refused by what `stat` says, before it is opened, so nothing blocks on a pipe without a writer
  and nothing reads an endless device.
- `LineReader` gives the lines with their numbers; a line longer than its bound is refused as soon
  as that many bytes are read without a newline.
- `json_value` refuses nesting deeper than `MAX_DEPTH` (and catches `json`'s own recursion guard).
- `json_records` ties them together for the JSON-lines files: the non-blank lines as values, a
  last line cut short (a writer killed mid-line) left out, an empty file refused.

Each refusal is a `ReadError` whose message is one line naming the file (and the line).
"""

from __future__ import annotations

import json
import os
import stat
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, BinaryIO, NamedTuple

#: the longest line read (bytes): far beyond any record the daemon or the proxy writes, and small
#: enough that what one line decodes to stays a few tens of MB at worst
MAX_LINE_BYTES = 1 << 20
#: the deepest JSON nesting read: a record is a few levels deep (a `move` record's knots: 4)
MAX_DEPTH = 64
#: how `stat` names what is not a regular file
_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISFIFO, "a named pipe (FIFO)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


class ReadError(Exception):
    """A file that cannot be read as what was asked; the message is one line naming it."""


class TooDeep(ValueError):
    """A JSON value nested deeper than `MAX_DEPTH`: hostile rather than torn, never skipped."""


def open_regular(path: Path, what: str) -> BinaryIO:
    """`path` opened for reading in binary, if it names a regular file (`what` names what it should
    hold, for the message)."""
    try:
        status = os.stat(path)
        if not stat.S_ISREG(status.st_mode):
            kind = next((name for test, name in _KINDS if test(status.st_mode)), "not a regular file")
            raise ReadError(f"{path}: is {kind}, not a {what} (only a regular file is read)")
        # O_NONBLOCK: should the path be swapped for a FIFO since the stat, the open does not wait
        flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0)
        descriptor = os.open(path, flags)
    except FileNotFoundError:
        raise ReadError(f"{path}: no such file") from None
    except OSError as exc:
        raise ReadError(f"{path}: cannot read it ({exc.strerror or exc})") from None
    file = os.fdopen(descriptor, "rb")
    opened = os.fstat(descriptor)
    if (opened.st_dev, opened.st_ino) != (status.st_dev, status.st_ino) or not stat.S_ISREG(opened.st_mode):
        file.close()
        raise ReadError(f"{path}: changed while being opened; not read")
    return file


class Line(NamedTuple):
    number: int
    #: without its newline
    data: bytes


class LineReader:
    """The lines of an open file from where it stands, each at most `max_line` bytes. `take`
    returns the next complete line, or None at the end of what is written so far. A last line
    without its newline is held back: a writer may still be writing it (`held`), and its rest is
    read with the next `take`; `keep_last` makes it a line of its own at the end instead (text
    files whose last line need not end in a newline)."""

    def __init__(
        self,
        file: BinaryIO,
        path: Path,
        what: str,
        *,
        max_line: int = MAX_LINE_BYTES,
        keep_last: bool = False,
    ):
        self.file = file
        self.path = path
        self.what = what
        self.max_line = max_line
        self.keep_last = keep_last
        #: the number of the last line taken
        self.number = 0
        self.held = b""

    def take(self) -> Line | None:
        data = self.held + self.file.readline(self.max_line + 1 - len(self.held))
        if data.endswith(b"\n"):
            self.held = b""
            self.number += 1
            return Line(self.number, data[:-1])
        if len(data) > self.max_line:
            raise ReadError(
                f"{self.path}:{self.number + 1}: a line longer than {_size(self.max_line)}, not a {self.what}"
            )
        if self.keep_last and data:
            self.held = b""
            self.number += 1
            return Line(self.number, data)
        self.held = data
        return None

    def __iter__(self) -> Iterator[Line]:
        while (line := self.take()) is not None:
            yield line


def _size(count: int) -> str:
    for shift, unit in ((20, "MiB"), (10, "KiB")):
        if count >= 1 << shift and count % (1 << shift) == 0:
            return f"{count >> shift} {unit}"
    return f"{count} bytes"


def json_value(data: bytes, *, constants: bool = True) -> Any:
    """One line's JSON value; ValueError (its reason) when it is not UTF-8, not JSON or nested
    deeper than `MAX_DEPTH`. `constants` False refuses NaN and Infinity."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise ValueError("not UTF-8 text") from None
    try:
        value = json.loads(text) if constants else json.loads(text, parse_constant=_refuse_constant)
    except RecursionError:  # json's own guard, far deeper than MAX_DEPTH: no traceback either way
        raise TooDeep(f"nested deeper than {MAX_DEPTH} levels") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"not JSON ({exc.msg}, column {exc.colno})") from None
    except ValueError as exc:  # an integer of more digits than Python converts, a refused constant
        raise ValueError(f"not JSON ({exc})") from None
    # a value cannot be deeper than its brackets are many: most lines need no walk
    if data.count(b"[") + data.count(b"{") > MAX_DEPTH and _deeper(value, MAX_DEPTH):
        raise TooDeep(f"nested deeper than {MAX_DEPTH} levels")
    return value


def _refuse_constant(name: str) -> None:
    raise ValueError(f"{name} is not a number here")


def _deeper(value: Any, limit: int) -> bool:
    """Whether arrays and objects nest deeper than `limit` in `value` (a walk without recursion, so
    a reader that recurses into the value later stays far from Python's limit)."""
    stack: list[tuple[Any, int]] = [(value, 1)]
    while stack:
        item, depth = stack.pop()
        if depth > limit:
            return True
        children = item.values() if isinstance(item, dict) else item
        stack.extend((child, depth + 1) for child in children if isinstance(child, (list, dict)))
    return False


def empty_error(path: Path, what: str) -> ReadError:
    return ReadError(f"{path}: empty, not a {what}")


def json_records(
    path: Path, what: str, *, constants: bool = True, on_line: Callable[[], None] | None = None
) -> Iterator[tuple[int, Any]]:
    """(line number, value) of each non-blank line of the JSON-lines file at `path`. A last line cut
    short (its writer was stopped mid-line) is left out; ReadError (`PATH:LINE: reason`) for a line
    that is not JSON, and for a file without a single record. `on_line` hears of each line read
    (progress)."""
    found = False
    with open_regular(path, what) as file:
        reader = LineReader(file, path, what)
        for number, data in reader:
            if on_line is not None:
                on_line()
            if not data.strip():
                continue
            try:
                value = json_value(data, constants=constants)
            except ValueError as exc:
                raise ReadError(f"{path}:{number}: not a {what}: {exc}") from None
            found = True
            yield number, value
        if reader.held.strip():  # a last line without its newline: whole, or cut short (left out)
            try:
                value = json_value(reader.held, constants=constants)
            except ValueError as exc:
                if not found:  # nothing but a broken line: no file cut short, not a file of records
                    raise ReadError(f"{path}:{reader.number + 1}: not a {what}: {exc}") from None
            else:
                found = True
                yield reader.number + 1, value
    if not found:
        raise empty_error(path, what)
