"""The bounded reader every offline command shares (emulator/tools/readers.py), the thinning `plot` uses
(emulator/tools/decimate.py) and the progress line (emulator/tools/progress.py); and, for each of `trace`,
`plot`, `replay` and `gcode --dry-run`, what it says of a file it must not read (issue "Hardening,
round two", item 5): one line naming the file, the command's bad-input status, no traceback."""

from __future__ import annotations

import io
import os
import threading
from pathlib import Path

import pytest
from click.testing import CliRunner

from emulator.cli import main
from emulator.tools.decimate import Buckets, ends, extremes
from emulator.tools.progress import EVERY, INTERVAL_S, Progress
from emulator.tools.readers import (
    MAX_DEPTH,
    LineReader,
    ReadError,
    TooDeep,
    json_records,
    json_value,
    open_regular,
)

# ---- open_regular -------------------------------------------------------------------------------


def test_only_a_regular_file_is_opened(tmp_path: Path) -> None:
    (tmp_path / "log.jsonl").write_text("{}\n")
    with open_regular(tmp_path / "log.jsonl", "traffic log") as file:
        assert file.read() == b"{}\n"
    for path, kind in ((tmp_path, "a directory"), (Path("/dev/zero"), "a character device")):
        with pytest.raises(ReadError) as raised:
            open_regular(path, "traffic log")
        assert str(raised.value) == f"{path}: is {kind}, not a traffic log (only a regular file is read)"
    with pytest.raises(ReadError, match=r"nope\.jsonl: no such file$"):
        open_regular(tmp_path / "nope.jsonl", "traffic log")


def test_a_fifo_without_a_writer_is_refused_at_once(tmp_path: Path) -> None:
    """Before, every reader blocked for ever in open() on a FIFO nobody writes to."""
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    outcome: list[BaseException] = []

    def attempt() -> None:
        try:
            open_regular(fifo, "session file").close()
        except ReadError as exc:
            outcome.append(exc)

    thread = threading.Thread(target=attempt, daemon=True)
    thread.start()
    thread.join(10.0)
    assert not thread.is_alive(), "open_regular blocked on the FIFO"
    assert [str(e) for e in outcome] == [
        f"{fifo}: is a named pipe (FIFO), not a session file (only a regular file is read)"
    ]


# ---- LineReader ---------------------------------------------------------------------------------


def test_lines_are_numbered_and_a_partial_last_line_is_held_until_its_rest_comes(tmp_path: Path) -> None:
    path = tmp_path / "t.txt"
    path.write_bytes(b"one\n\nthr")
    with path.open("rb") as file:
        reader = LineReader(file, path, "log")
        assert list(reader) == [(1, b"one"), (2, b"")]
        assert reader.held == b"thr"
        with path.open("ab") as more:
            more.write(b"ee\nfour")
        assert reader.take() == (3, b"three")
        assert reader.take() is None and reader.held == b"four"
    with path.open("rb") as file:
        lines = LineReader(file, path, "log", keep_last=True)
        assert b"|".join(line.data for line in lines) == b"one||three|four", "the last line is one"


def test_a_line_over_the_bound_is_refused_once_that_much_is_read(tmp_path: Path) -> None:
    path = tmp_path / "t.txt"
    path.write_bytes(b"short\n" + b"x" * 100 + b"\n" + b"y" * 5000)
    with path.open("rb") as file:
        reader = LineReader(file, path, "G-code program", max_line=100, keep_last=True)
        assert reader.take() == (1, b"short")
        assert reader.take() == (2, b"x" * 100), "exactly the bound is allowed"
        with pytest.raises(ReadError) as raised:
            reader.take()
        assert str(raised.value) == f"{path}:3: a line longer than 100 bytes, not a G-code program"
        assert file.tell() <= 6 + 101 + 101, "no more was read than the bound and one byte"


# ---- JSON values --------------------------------------------------------------------------------


def test_json_nesting_is_bounded_without_recursion() -> None:
    """Before: json.loads of 100 000 `[` raised RecursionError, a traceback in every reader."""
    with pytest.raises(TooDeep, match="nested deeper than 64 levels"):
        json_value(b"[" * 100_000)
    assert json_value(b"[" * MAX_DEPTH + b"]" * MAX_DEPTH) is not None
    with pytest.raises(TooDeep):
        json_value(b'{"a": ' * (MAX_DEPTH + 1) + b"1" + b"}" * (MAX_DEPTH + 1))
    wide = b"[" + b",".join([b"[[1]]"] * 500) + b"]"
    assert len(json_value(wide)) == 500, "many brackets, little depth"


@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (b"\xff\xfe", "not UTF-8 text"),
        (b"{", "not JSON (Expecting property name enclosed in double quotes, column 2)"),
        (b"9" * 5000, "not JSON (Exceeds the limit"),
    ],
)
def test_what_is_not_json_says_why(data: bytes, reason: str) -> None:
    with pytest.raises(ValueError) as raised:
        json_value(data)
    assert str(raised.value).startswith(reason)


def test_json_constants_can_be_refused() -> None:
    assert json_value(b"NaN") != 0
    with pytest.raises(ValueError, match="NaN is not a number here"):
        json_value(b"NaN", constants=False)


def test_json_records_skip_blank_lines_and_a_torn_last_line(tmp_path: Path) -> None:
    path = tmp_path / "t.jsonl"
    path.write_bytes(b'{"a": 1}\n\n{"b": 2}\n{"c":')
    assert list(json_records(path, "log")) == [(1, {"a": 1}), (3, {"b": 2})]
    path.write_bytes(b'{"a": 1}\n{"b": 2}')
    assert list(json_records(path, "log")) == [(1, {"a": 1}), (2, {"b": 2})], "whole without its newline"


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"", "t.jsonl: empty, not a session file"),
        (b"\n \n", "t.jsonl: empty, not a session file"),
        (b"\xff\xfe\x00", "t.jsonl:1: not a session file: not UTF-8 text"),
        (b'{"a": 1}\nnope\n', "t.jsonl:2: not a session file: not JSON (Expecting value, column 1)"),
    ],
)
def test_json_records_errors_name_the_file_and_line(tmp_path: Path, content: bytes, message: str) -> None:
    path = tmp_path / "t.jsonl"
    path.write_bytes(content)
    with pytest.raises(ReadError) as raised:
        list(json_records(path, "session file"))
    assert str(raised.value) == f"{tmp_path}/{message}"


# ---- thinning -----------------------------------------------------------------------------------


def test_buckets_keep_everything_up_to_the_limit() -> None:
    kept: Buckets[int] = Buckets(100, extremes)
    for i in range(100):
        kept.add(float(i), i, float(i % 7))
    assert kept.items() == list(range(100)) and not kept.decimated


def test_buckets_past_the_limit_keep_the_extremes_and_ends_in_time_order() -> None:
    kept: Buckets[tuple[float, float]] = Buckets(400, extremes)
    values = [((i * 7919) % 1000) - 500.0 for i in range(100_000)]
    values[54_321] = 10_000.0  # one spike: min/max per bucket must keep it
    for i, value in enumerate(values):
        kept.add(i * 0.01, (i * 0.01, value), value)
    items = kept.items()
    assert kept.decimated and len(items) <= 400 and kept.added == 100_000
    assert [t for t, _ in items] == sorted(t for t, _ in items)
    assert items[0] == (0.0, values[0]) and items[-1] == (999.99, values[-1])
    assert max(v for _, v in items) == 10_000.0 and min(v for _, v in items) == min(values)


def test_end_buckets_keep_first_and_last_of_each_stretch_in_any_order_of_arrival() -> None:
    kept: Buckets[int] = Buckets(40, ends)
    for i in [*range(500, 1000), *range(500)]:  # the earlier half arrives last
        kept.add(float(i), i)
    items = kept.items()
    assert len(items) <= 40 and items == sorted(items) and items[0] == 0 and items[-1] == 999


# ---- progress -----------------------------------------------------------------------------------


class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_is_one_updating_line_on_a_terminal_wiped_at_the_end() -> None:
    now = [0.0]
    terminal = FakeTerminal()
    with Progress("reading t.jsonl", stream=terminal, clock=lambda: now[0]) as progress:
        for _ in range(EVERY - 1):
            progress.tick()
        assert terminal.getvalue() == "", "a short job stays silent"
        progress.tick()
        assert terminal.getvalue() == f"\rreading t.jsonl: {EVERY:,} lines\x1b[K"
        for _ in range(EVERY):
            progress.tick()
        assert terminal.getvalue().count("\r") == 1, "not redrawn before INTERVAL_S"
        now[0] += INTERVAL_S
        for _ in range(EVERY):
            progress.tick()
        assert terminal.getvalue().endswith(f"\rreading t.jsonl: {3 * EVERY:,} lines\x1b[K")
    assert terminal.getvalue().endswith("\r\x1b[K")


def test_progress_says_nothing_when_stderr_is_no_terminal_or_output_shows_it() -> None:
    for stream, enabled in ((io.StringIO(), True), (FakeTerminal(), False)):
        with Progress("x", stream=stream, enabled=enabled) as progress:
            for _ in range(5 * EVERY):
                progress.tick()
        assert stream.getvalue() == ""


# ---- every reader's command ---------------------------------------------------------------------

#: each command, its arguments around the file, and the exit status it documents for bad input
COMMANDS = {
    "trace": ([], 1),
    "plot": (["-o", "{tmp}/out.png"], 1),
    "replay": (["--timing", "fast"], 2),
    "gcode": (["--dry-run"], 1),
}
WHAT = {"trace": "traffic log", "plot": "traffic log", "replay": "session file", "gcode": "G-code program"}


def _hostile(tmp_path: Path, case: str) -> tuple[Path, str]:
    """A hostile input and the start of what must be said of it (after `PATH`)."""
    if case == "dev_zero":
        return Path("/dev/zero"), ": is a character device"
    if case == "directory":
        return tmp_path, ": is a directory"
    path = tmp_path / f"{case}.in"
    if case == "huge_line":
        path.write_bytes(b"7" * (3 << 20))
        return path, ":1: a line longer than "
    if case == "deep_nesting":
        path.write_bytes(b"[" * 100_000 + b"\n")
        return path, ":1: "
    path.write_bytes(b"")
    return path, ": empty, not a "


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("case", ["dev_zero", "directory", "huge_line", "deep_nesting", "empty"])
def test_each_reader_refuses_a_hostile_file_in_one_line(tmp_path: Path, command: str, case: str) -> None:
    """Before: /dev/zero grew replay to gigabytes and plot to a MemoryError traceback, trace read it
    for ever; the nesting was a RecursionError traceback; click refused a directory for replay and
    gcode with a usage error (status 2, several lines)."""
    path, said = _hostile(tmp_path, case)
    extra, status = COMMANDS[command]
    args = [command, str(path), *(arg.format(tmp=tmp_path) for arg in extra)]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == status, result.output
    assert isinstance(result.exception, SystemExit), "no traceback"
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"stage-emu: {path}{said}"), result.stderr
    if case not in ("huge_line", "dev_zero", "directory") and command != "gcode":
        assert WHAT[command] in lines[0]
