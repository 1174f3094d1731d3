"""`stage-emu trace`: reading a traffic log back as exchanges (emulator/tools/trace.py,
emulator/cli/trace.py)."""

from __future__ import annotations

import json
import math
import os
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from emulator.cli import main
from emulator.tools.readers import ReadError
from emulator.tools.trace import (
    Record,
    TraceNotes,
    TraceOptions,
    Tracer,
    clock_time,
    parse_record,
    readable,
    reply_gist,
    trace_lines,
)

WALL = 1_700_000_000.25
AT = clock_time(WALL)


def traffic(t: float, direction: str, data: bytes, kind: str, summary: str | None = None, **more: Any) -> str:
    entry: dict[str, Any] = {"t": t, "wall": WALL, "device": "stage", "port": "main", "dir": direction}
    entry.update(hex=data.hex(" "), kind=kind, **more)
    if summary is not None:
        entry["summary"] = summary
    return json.dumps(entry)


def event(t: float, ev: str, device: str = "stage", **fields: Any) -> str:
    return json.dumps({"t": t, "wall": WALL, "device": device, "dir": "ev", "ev": ev, **fields})


WHERE = traffic(2.00625, "rx", b"W X Y\r", "frame", "W X Y [WHERE]")
WHERE_REPLY = traffic(2.014583, "tx", b":A 0 0\r\n", "reply", ":A 0 0\\r\\n (reply to W X Y [WHERE])")
MOVE = traffic(2.309375, "rx", b"M X=1000\r", "frame", "M X=1000 [MOVE]")
MOVE_LEG = event(2.309375, "move", path={"X": [[2.309375, 0.0], [2.383145, 1000.0]]})
MOVE_REPLY = traffic(2.313542, "tx", b":A\r\n", "reply", ":A\\r\\n (reply to M X=1000 [MOVE])")
MOVE_DONE = event(2.383145, "move_complete", positions={"X": "1000"})
HUNG = traffic(3.5, "rx", b"W X\r", "lost", "hang fault: the device hears nothing")
LOG = [WHERE, WHERE_REPLY, MOVE, MOVE_LEG, MOVE_REPLY, MOVE_DONE, HUNG]

EXPECTED = [
    f'   2.006250  {AT}  stage/main  W X Y [WHERE]  "W X Y\\r"  -> ":A 0 0\\r\\n"  [8.3 ms]',
    f'   2.309375  {AT}  stage/main  M X=1000 [MOVE]  "M X=1000\\r"  -> ":A\\r\\n"  [4.2 ms]',
    f'   2.383145  {AT}  stage  * move_complete positions={{"X": "1000"}}',
    f'   3.500000  {AT}  stage/main  LOST "W X\\r" (hang fault: the device hears nothing)',
]


def write_log(path: Path, lines: list[str], end: str = "\n") -> Path:
    path.write_text("\n".join(lines) + end, encoding="utf-8")
    return path


def traced(lines: list[str], **options: Any) -> list[str]:
    tracer = Tracer(TraceOptions(**options))
    out = [line for text in lines for line in tracer.feed(parse_record(text))]
    return out + tracer.finish()


# ---- formatting ------------------------------------------------------------------------------------


def test_bytes_read_as_printable_ascii_and_escapes() -> None:
    assert readable(b'W X\r\n\x00\xff"\\') == '"W X\\r\\n\\x00\\xff\\"\\\\"'


@pytest.mark.parametrize(
    ("summary", "asked", "gist"),
    [
        (":A 0 0\\r\\n (reply to W X Y [WHERE])", "W X Y [WHERE]", ""),
        ("reply to c: position X=0 Y=0 Z=0 (µsteps)", "c", "position X=0 Y=0 Z=0 (µsteps)"),
        (
            "not sent: drop fault: reply to c: error '1' frame error",
            "c",
            "not sent: drop fault: error '1' frame error",
        ),
        ("reply to c", "c", ""),
        ("reply to something else", "c", "reply to something else"),
        (None, "c", ""),
    ],
)
def test_reply_gist_drops_what_the_line_already_shows(summary: str | None, asked: str, gist: str) -> None:
    shown = ":A 0 0\\r\\n" if "A 0 0" in (summary or "") else "\\x00"
    assert reply_gist(summary, asked, shown) == gist


def test_records_that_are_not_traffic_are_refused() -> None:
    for text in ("[]", '{"t": 1}', '{"t": true, "wall": 1, "device": "d", "dir": "ev", "ev": "x"}', "{"):
        with pytest.raises(ValueError):
            parse_record(text)
    with pytest.raises(ValueError):
        parse_record(traffic(1.0, "rx", b"", "frame").replace('"hex": ""', '"hex": "zz"'))
    assert parse_record(HUNG) == Record(
        3.5, WALL, "stage", "rx", "main", b"W X\r", "lost", "hang fault: the device hears nothing"
    )


# ---- pairing ---------------------------------------------------------------------------------------


def test_requests_pair_with_replies_and_events_follow_the_exchange_they_came_during() -> None:
    assert traced(LOG) == EXPECTED


def test_all_events_include_the_per_leg_move_records_and_none_hides_them() -> None:
    with_moves = traced(LOG, events="all")
    assert with_moves[2].startswith(f"   2.309375  {AT}  stage  * move path=")
    assert with_moves[3] == EXPECTED[2]
    assert traced(LOG, events="none") == [EXPECTED[0], EXPECTED[1], EXPECTED[3]]


def test_stray_units_garbled_bytes_lost_replies_and_unsolicited_output() -> None:
    lines = traced(
        [
            traffic(2.0, "rx", b"\x1e", "garbled", "garbled: the device read 1E from the host's 63"),
            traffic(2.6, "rx", b"\x1ec\r", "stray", "CR ending a bad frame (error '1' owed)"),
            traffic(
                2.6,
                "tx",
                b"1\r",
                "lost",
                "not sent: drop fault: reply to CR ending a bad frame "
                "(error '1' owed): error '1' frame error",
            ),
            traffic(3.0, "tx", b"N\r\n", "unsolicited", "status"),
            traffic(3.1, "rx", b"", "lost", "the host hung up: 4 bytes left in the port discarded"),
        ]
    )
    assert lines == [
        f'   2.000000  {AT}  stage/main  GARBLED "\\x1e" (the device read 1E from the host\'s 63)',
        f"   2.600000  {AT}  stage/main  STRAY \"\\x1ec\\r\" (CR ending a bad frame (error '1' owed))"
        "  -> LOST \"1\\r\" (not sent: drop fault: error '1' frame error)  [0.0 ms]",
        f'   3.000000  {AT}  stage/main  -> UNSOLICITED "N\\r\\n" status',
        f"   3.100000  {AT}  stage/main  LOST (the host hung up: 4 bytes left in the port discarded)",
    ]


def test_a_request_without_a_reply_says_so_when_the_next_one_comes_or_the_log_ends() -> None:
    first = traffic(1.0, "rx", b"x\r", "frame", "x")
    second = traffic(2.0, "rx", b"y\r", "frame", "y")
    assert traced([first, second]) == [
        f'   1.000000  {AT}  stage/main  x  "x\\r"  -> no reply',
        f'   2.000000  {AT}  stage/main  y  "y\\r"  -> no reply',
    ]


def test_requests_waiting_too_long_are_shown_without_their_reply() -> None:
    tracer = Tracer(TraceOptions())
    assert tracer.feed(parse_record(WHERE)) == []
    assert tracer.feed(parse_record(MOVE_DONE)) == [], "held behind the open request"
    assert tracer.expire(WALL) == [], "written at WALL: not before it"
    assert tracer.expire(WALL + 1, "no reply within 1 s") == [
        f'   2.006250  {AT}  stage/main  W X Y [WHERE]  "W X Y\\r"  -> no reply within 1 s',
        EXPECTED[2],
    ]
    assert tracer.feed(parse_record(WHERE_REPLY)) == [
        f'   2.014583  {AT}  stage/main  -> REPLY ":A 0 0\\r\\n" :A 0 0\\r\\n (reply to W X Y [WHERE])'
    ]


def test_device_and_port_filters() -> None:
    other = event(2.5, "move_complete", device="other")
    aux = traffic(2.6, "tx", b"1", "unsolicited", "TTL report", port="aux").replace('"main"', '"aux"')
    assert traced([*LOG, other, aux], device="stage", port="main") == EXPECTED
    assert traced([*LOG, other, aux], port="aux") == [
        EXPECTED[2],
        f"   2.500000  {AT}  other  * move_complete",
        f'   2.600000  {AT}  stage/aux  -> UNSOLICITED "1" TTL report',
    ]


# ---- reading a file --------------------------------------------------------------------------------


def test_a_whole_log_is_traced_and_a_truncated_last_line_skipped(tmp_path: Path) -> None:
    path = write_log(tmp_path / "t.jsonl", [*LOG, WHERE[:30]], end="")
    notes = TraceNotes()
    assert list(trace_lines(path, TraceOptions(), notes=notes)) == EXPECTED
    assert notes.incomplete_tail and notes.malformed == 0


@pytest.mark.parametrize(
    ("make", "options", "message"),
    [
        (lambda p: p, TraceOptions(), "t.jsonl: no such file"),
        (lambda p: write_log(p, ["hello", *LOG]), TraceOptions(), "t.jsonl:1: not a traffic log"),
        (
            lambda p: write_log(p, LOG),
            TraceOptions(device="stag"),
            "no device 'stag' in this log (it has: stage)",
        ),
        (lambda p: write_log(p, LOG), TraceOptions(port="aux"), "no port 'aux' in this log (it has: main)"),
    ],
    ids=["missing", "not-a-log", "unknown-device", "unknown-port"],
)
def test_bad_input_is_one_error(
    tmp_path: Path, make: Callable[[Path], Path], options: TraceOptions, message: str
) -> None:
    path = make(tmp_path / "t.jsonl")
    lines: list[str] = []
    with pytest.raises(ReadError, match=message.replace("(", r"\(").replace(")", r"\)")):
        lines.extend(trace_lines(path, options))
    assert lines == [], "nothing is printed before the error"


def test_malformed_lines_after_the_first_are_skipped_and_counted(tmp_path: Path) -> None:
    path = write_log(tmp_path / "t.jsonl", [WHERE, "{garbage", "", WHERE_REPLY])
    notes = TraceNotes()
    assert list(trace_lines(path, TraceOptions(), notes=notes)) == EXPECTED[:1]
    assert notes.malformed == 1


# ---- following -------------------------------------------------------------------------------------


class Follower:
    """`trace_lines(..., follow=True)` on a thread, its lines collected for a bounded wait."""

    def __init__(self, path: Path, reply_wait_s: float = math.inf) -> None:
        self.lines: list[str] = []
        self.changed = threading.Condition()
        self.stop = threading.Event()
        self.error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, args=(path, reply_wait_s), daemon=True)
        self._thread.start()

    def _run(self, path: Path, reply_wait_s: float) -> None:
        options = TraceOptions()
        try:
            for line in trace_lines(
                path, options, follow=True, stop=self.stop, poll_s=0.01, reply_wait_s=reply_wait_s
            ):
                with self.changed:
                    self.lines.append(line)
                    self.changed.notify_all()
        except BaseException as exc:  # reported by the test's thread
            self.error = exc

    def wait_for(self, count: int, timeout: float = 5.0) -> list[str]:
        with self.changed:
            assert self.changed.wait_for(lambda: len(self.lines) >= count, timeout), self.lines
            return list(self.lines)

    def finish(self) -> list[str]:
        self.stop.set()
        self._thread.join(5.0)
        assert not self._thread.is_alive() and self.error is None, self.error
        return self.lines


def append(path: Path, text: str) -> None:
    with path.open("a", encoding="utf-8") as file:
        file.write(text)
        file.flush()


@pytest.fixture
def follow_log(tmp_path: Path) -> Iterator[tuple[Path, Follower]]:
    path = write_log(tmp_path / "t.jsonl", [WHERE])
    follower = Follower(path)
    yield path, follower
    follower.stop.set()


def test_follow_reads_what_is_appended_and_waits_for_the_rest_of_a_line(
    follow_log: tuple[Path, Follower],
) -> None:
    path, follower = follow_log
    pieces = [WHERE_REPLY[:20], WHERE_REPLY[20:] + "\n", MOVE + "\n", MOVE_LEG + "\n" + MOVE_REPLY + "\n"]

    def writer() -> None:
        for piece in pieces:
            append(path, piece)

    appender = threading.Thread(target=writer)
    appender.start()
    appender.join(5.0)
    assert follower.wait_for(2) == EXPECTED[:2]
    append(path, HUNG[:10])
    assert follower.finish() == EXPECTED[:2], "a line still being written is not shown"


def test_follow_goes_on_in_a_replaced_log_and_starts_over_in_a_truncated_one(
    follow_log: tuple[Path, Follower],
) -> None:
    path, follower = follow_log
    append(path, WHERE_REPLY + "\n")
    assert follower.wait_for(1) == EXPECTED[:1]
    rotated = path.with_suffix(".1")
    os.rename(path, rotated)  # logrotate, then the daemon reopens the path on SIGUSR1
    append(rotated, MOVE + "\n")
    write_log(path, [MOVE_REPLY])
    assert follower.wait_for(2) == EXPECTED[:2], "the old file is read to its end, then the new one"
    done = event(4.0, "halted")  # shorter than what was read: the follower sees the file shrank
    path.write_text(done + "\n")  # copytruncate: the same file, emptied and written again
    assert follower.wait_for(3)[2] == f"   4.000000  {AT}  stage  * halted"
    assert follower.finish() == [*EXPECTED[:2], f"   4.000000  {AT}  stage  * halted"]


# ---- the command -----------------------------------------------------------------------------------


def test_cli_prints_exchanges_and_notes_a_truncated_last_line(tmp_path: Path) -> None:
    path = write_log(tmp_path / "t.jsonl", [*LOG, WHERE[:30]], end="")
    result = CliRunner().invoke(main, ["trace", str(path)])
    assert result.exit_code == 0, result.output
    assert result.stdout.splitlines() == EXPECTED
    assert (
        result.stderr == f"stage-emu: {path}: the last line is incomplete (still being written?); skipped\n"
    )


@pytest.mark.parametrize(
    ("lines", "args", "message"),
    [
        (None, [], "no such file"),
        (["not json"], [], "not a traffic log"),
        (LOG, ["--device", "nope"], "no device 'nope' in this log (it has: stage)"),
    ],
)
def test_cli_bad_input_is_one_line_and_exit_1(
    tmp_path: Path, lines: list[str] | None, args: list[str], message: str
) -> None:
    path = tmp_path / "t.jsonl"
    if lines is not None:
        write_log(path, lines)
    result = CliRunner().invoke(main, ["trace", str(path), *args])
    assert result.exit_code == 1
    assert result.stdout == ""
    assert result.stderr.startswith(f"stage-emu: {path}") and message in result.stderr
    assert len(result.stderr.splitlines()) == 1 and result.exception is not None
    assert isinstance(result.exception, SystemExit), "no traceback"


# ---- bounded reading (issue "Hardening, round two", item 5) ------------------------------------------


def test_cli_empty_log_is_one_line_and_exit_1_like_plot_and_replay(tmp_path: Path) -> None:
    """An empty log is no log to trace: before, `trace` exited 0 silently while `plot` said so."""
    path = tmp_path / "t.jsonl"
    for content in ("", "\n  \n"):
        path.write_text(content)
        result = CliRunner().invoke(main, ["trace", str(path)])
        assert (result.exit_code, result.stdout) == (1, "")
        assert result.stderr == f"stage-emu: {path}: empty, not a traffic log\n"


def test_follow_waits_on_an_empty_log_for_its_first_records(tmp_path: Path) -> None:
    """A daemon just started has written nothing yet: following its log is no error."""
    path = tmp_path / "t.jsonl"
    path.write_text("")
    follower = Follower(path)
    append(path, WHERE + "\n" + WHERE_REPLY + "\n")
    assert follower.wait_for(1) == EXPECTED[:1]
    assert follower.finish() == EXPECTED[:1]


def test_follow_keeps_a_partial_line_of_any_batch_until_its_rest_comes(tmp_path: Path) -> None:
    """More lines than one read returns, the last of them cut: all arrive, in order, once."""
    path = tmp_path / "t.jsonl"
    many = [event(float(i), "halted") for i in range(5000)]
    text = "".join(line + "\n" for line in many)
    path.write_text(text[:-30])
    follower = Follower(path)
    follower.wait_for(4999)
    append(path, text[-30:])
    lines = follower.wait_for(5000)
    assert lines == [f"{float(i):11.6f}  {AT}  stage  * halted" for i in range(5000)]
    follower.finish()


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"[" * 100_000 + b"\n", "t.jsonl:1: not a traffic log: nested deeper than 64 levels"),
        (b"x" * (2 << 20), "t.jsonl:1: a line longer than 1 MiB, not a traffic log"),
    ],
    ids=["deep-nesting", "huge-line"],
)
def test_cli_hostile_lines_are_one_line_naming_the_line(tmp_path: Path, content: bytes, message: str) -> None:
    """Before: a RecursionError traceback for the nesting; a line of any length read whole."""
    path = tmp_path / "t.jsonl"
    path.write_bytes(content)
    result = CliRunner().invoke(main, ["trace", str(path)])
    assert result.exit_code == 1 and isinstance(result.exception, SystemExit)
    assert result.stderr == f"stage-emu: {tmp_path}/{message}\n"


def test_deep_nesting_after_the_first_record_is_an_error_not_a_skipped_line(tmp_path: Path) -> None:
    path = tmp_path / "t.jsonl"
    path.write_bytes(f"{WHERE}\n{WHERE_REPLY}\n".encode() + b"[" * 70 + b"]" * 70 + b"\n")
    with pytest.raises(ReadError, match=r"t\.jsonl:3: not a traffic log: nested deeper than 64 levels"):
        list(trace_lines(path, TraceOptions()))
