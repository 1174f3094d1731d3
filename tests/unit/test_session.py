"""Session files (emulator/tools/session.py) and the pairing of requests with replies
(emulator/tools/session_decode.py), on synthetic records."""

from __future__ import annotations

import json
import tracemalloc
from pathlib import Path

import pytest

from emulator.device import HostLine, LineSettings
from emulator.tools.session import (
    RX,
    TX,
    Chunk,
    Header,
    LineChange,
    Session,
    SessionError,
    SessionWriter,
    decode,
    load_session,
    save_session,
)
from emulator.tools.session_decode import Exchange
from protocols.mp285 import Move, encode_position

LINE = LineSettings(baud=9600, data_bits=8, parity="none", stop_bits=1, rtscts=False, xonxoff=False)


def pairs(family: str, *events: tuple[float, str, bytes]) -> list[tuple[bytes | None, bytes]]:
    found = decode(family, [Chunk(t, d, data) for t, d, data in events])
    return [(None if e.request is None else e.request.data, e.reply) for e in found]


# ---- MS2000 ---------------------------------------------------------------------------------------


def test_ms2000_a_request_and_its_reply_with_latencies() -> None:
    [exchange] = decode(
        "ms2000", [Chunk(1.0, RX, b"W X\r"), Chunk(1.004, TX, b":A "), Chunk(1.008, TX, b"0\r\n")]
    )
    assert exchange.request is not None and exchange.request.summary == "W X [WHERE]"
    assert exchange.reply == b":A 0\r\n"
    assert exchange.first_latency == pytest.approx(0.004) and exchange.latency == pytest.approx(0.008)
    assert exchange.describe("ms2000") == 'W X [WHERE] -> ":A 0\\r\\n"'


def test_ms2000_a_request_typed_a_byte_at_a_time_ends_at_its_cr() -> None:
    events = [(0.001 * i, RX, bytes((b,))) for i, b in enumerate(b"W X\r")] + [(0.01, TX, b":A 0\r\n")]
    [exchange] = decode("ms2000", [Chunk(*e) for e in events])
    assert exchange.t == pytest.approx(0.003) and exchange.latency == pytest.approx(0.007)


def test_ms2000_commands_sent_in_one_write_get_their_own_replies() -> None:
    assert pairs("ms2000", (0, RX, b"W X\rW Y\r"), (0.01, TX, b":A 1\r\n:A"), (0.02, TX, b" 2\r\n")) == [
        (b"W X\r", b":A 1\r\n"),
        (b"W Y\r", b":A 2\r\n"),
    ]


def test_ms2000_cr_only_replies_end_when_the_next_request_is_answered() -> None:
    # VB X bit 3: replies end in CR alone; a later request's bytes close the earlier reply
    assert pairs(
        "ms2000", (0, RX, b"W X\r"), (0.01, TX, b":A 1\r"), (0.02, RX, b"W Y\r"), (0.03, TX, b":A 2\r")
    ) == [
        (b"W X\r", b":A 1\r"),
        (b"W Y\r", b":A 2\r"),
    ]


def test_ms2000_a_lf_after_the_next_request_still_belongs_to_its_reply() -> None:
    assert pairs(
        "ms2000", (0, RX, b"W X\r"), (0.01, TX, b":A 1\r"), (0.011, RX, b"W Y\r"), (0.012, TX, b"\n:A 2\r\n")
    ) == [
        (b"W X\r", b":A 1\r\n"),
        (b"W Y\r", b":A 2\r\n"),
    ]


def test_ms2000_output_with_no_request_waiting_is_unsolicited() -> None:
    assert pairs("ms2000", (0, TX, b"X"), (0.1, RX, b"/\r"), (0.11, TX, b"N\r\n"), (0.2, TX, b"Y")) == [
        (None, b"X"),
        (b"/\r", b"N\r\n"),
        (None, b"Y"),
    ]


def test_a_request_left_unanswered_when_the_host_writes_again() -> None:
    assert pairs("ms2000", (0, RX, b"\r"), (0.5, RX, b"W X\r"), (0.51, TX, b":A 0\r\n")) == [
        (b"\r", b""),
        (b"W X\r", b":A 0\r\n"),
    ]


def test_an_unfinished_exchange_is_closed_at_the_end() -> None:
    assert pairs("ms2000", (0, RX, b"W X\r"), (0.01, TX, b":A")) == [(b"W X\r", b":A")]


# ---- MP-285 ---------------------------------------------------------------------------------------


def test_mp285_a_position_reply_is_complete_by_its_length_not_by_a_cr_inside() -> None:
    position = encode_position(13, 0x0D0D, 0)  # 0D bytes inside the reply
    assert pairs("mp285", (0, RX, b"c\r"), (0.01, TX, position[:5]), (0.02, TX, position[5:] + b"\r")) == [
        (b"c\r", position),
        (None, b"\r"),
    ]


def test_mp285_frames_delimited_by_the_parser() -> None:
    move = Move(250, 0, 0).encode()
    found = decode(
        "mp285", [Chunk(0, RX, move[:5]), Chunk(0.001, RX, move[5:] + b"r\r"), Chunk(0.3, TX, b"\r")]
    )
    assert [(e.request.summary if e.request else None, e.reply) for e in found] == [
        ("m X=250 Y=0 Z=0 (µsteps)", b"\r"),
        ("r", b""),  # a reset has no reply: it takes nothing from the move
    ]
    assert found[0].describe("mp285") == "m X=250 Y=0 Z=0 (µsteps) -> CR (done)"


def test_mp285_interrupt_during_a_move_and_an_error_reply() -> None:
    move = Move(2500, 0, 0).encode()
    assert pairs(
        "mp285",
        (0, RX, move),
        (0.1, RX, b"\x03"),
        (0.101, TX, b"="),
        (0.3, TX, b"\r"),
        (0.4, RX, b"x\r"),
        (0.41, TX, b"4\r"),
    ) == [(move, b""), (b"\x03", b"=\r"), (b"x\r", b"4\r")]


def test_mp285_an_upload_reply_is_as_long_as_its_vector_count_says() -> None:
    program = bytes((1,)) + bytes(16) + b"\r"  # one 16-byte vector
    assert pairs("mp285", (0, RX, b"u\x01\r"), (0.01, TX, program), (0.02, RX, b"c\r")) == [
        (b"u\x01\r", program),
        (b"c\r", b""),
    ]


# ---- the file ------------------------------------------------------------------------------------


def write_session(path: Path) -> None:
    writer = SessionWriter(path, Header("ms2000", "ms2000", LINE, "/dev/ttyUSB0"))
    writer.line(0.1, HostLine(baud=9600, stop_bits=1, rtscts=False, xonxoff=False))
    writer.chunk(0.2, RX, b"W X\r")
    writer.chunk(0.21, TX, b":A 0\r\n")
    writer.chunk(0.205, RX, b"V\r")  # stamped by another thread a little earlier: kept in order
    writer.close(1.0)


def test_a_written_session_reads_back(tmp_path: Path) -> None:
    path = tmp_path / "s.jsonl"
    write_session(path)
    records = [json.loads(line) for line in path.read_text().splitlines()]
    assert [r.get("dir") for r in records] == [None, "line", "rx", "tx", "exchange", "rx", "exchange", "end"]
    assert records[4] == {
        "t": 0.2,
        "dir": "exchange",
        "request": "57 20 58 0d",
        "reply": "3a 41 20 30 0d 0a",
        "summary": 'W X [WHERE] -> ":A 0\\r\\n"',
        "latency": 0.01,
    }
    session = load_session(path)
    assert session.header == Header("ms2000", "ms2000", LINE, "/dev/ttyUSB0", records[0]["started"])
    assert session.complete
    assert tuple(session.events) == (
        LineChange(0.1, HostLine(baud=9600, stop_bits=1, rtscts=False, xonxoff=False)),
        Chunk(0.2, RX, b"W X\r"),
        Chunk(0.21, TX, b":A 0\r\n"),
        Chunk(0.21, RX, b"V\r"),
    )
    copy = tmp_path / "copy.jsonl"
    assert save_session(session, copy) == 2
    assert tuple(load_session(copy).events) == tuple(session.events)


def test_an_existing_file_is_not_overwritten(tmp_path: Path) -> None:
    path = tmp_path / "s.jsonl"
    path.write_text("mine\n")
    with pytest.raises(SessionError, match="already exists"):
        SessionWriter(path, Header("ms2000", "ms2000", LINE))
    assert path.read_text() == "mine\n"


def test_a_session_cut_short_keeps_what_it_holds(tmp_path: Path) -> None:
    path = tmp_path / "s.jsonl"
    write_session(path)
    lines = path.read_text().splitlines()
    path.write_text("\n".join(lines[:4]) + '\n{"t": 0.3, "dir": "t')  # killed mid-line, no end record
    session = load_session(path)
    assert not session.complete and len(tuple(session.events)) == 3


HEADER = json.dumps(
    {"session": "stage-emu", "version": 1, "device": "ms2000", "profile": "ms2000", "line": {
        "baud": 9600, "data_bits": 8, "parity": "none", "stop_bits": 1}}
)  # fmt: skip


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ("", "empty, not a session file"),
        ("{}\n", ':1: not a stage-emu session (no "session": "stage-emu" header'),
        ("[1]\n", ":1: not a JSON object; not a session file"),
        (HEADER.replace('"version": 1', '"version": 7') + "\n", ":1: session format version 7"),
        (HEADER.replace('"ms2000", "profile"', '"lamp", "profile"') + "\n", ":1: device must be one of"),
        (HEADER.replace("9600", "-1") + "\n", ":1: baud -1 is not a valid setting"),
        (HEADER.replace(', "stop_bits": 1', "") + "\n", ":1: line needs baud"),
        (HEADER + '\n{"t": 1, "dir": "rx", "hex": "0"}\n', ":2: hex must be bytes as hex digits"),
        (HEADER + '\n{"t": 1, "dir": "rx", "hex": ""}\n', ":2: a rx record without bytes"),
        (
            HEADER + '\n{"t": NaN, "dir": "rx", "hex": "00"}\n',
            ":2: not a session file: not JSON (NaN is not a number here)",
        ),
        (HEADER + '\n{"t": "1", "dir": "rx", "hex": "00"}\n', ":2: t must be seconds since the start"),
        (
            HEADER + '\n{"t": 2, "dir": "rx", "hex": "00"}\n{"t": 1, "dir": "tx", "hex": "00"}\n',
            ":3: t goes backwards",
        ),
        (HEADER + '\n{"t": 1, "dir": "sideways"}\n', ":2: unknown record dir 'sideways'"),
        (
            HEADER + '\n{"t": 1, "dir": "line", "parity": "mark"}\n',
            ":2: parity 'mark' is not a valid setting",
        ),
        (HEADER + "\nnot json\n" + '{"t": 1, "dir": "end"}\n', ":2: not a session file: not JSON"),
    ],
)
def test_a_malformed_session_is_one_line_naming_the_place(tmp_path: Path, text: str, problem: str) -> None:
    path = tmp_path / "bad.jsonl"
    path.write_text(text)
    with pytest.raises(SessionError) as raised:
        load_session(path)
    message = str(raised.value)
    assert message.startswith(str(path)) and problem in message and "\n" not in message


def test_a_file_that_is_not_there_or_not_text(tmp_path: Path) -> None:
    with pytest.raises(SessionError, match="no such file"):
        load_session(tmp_path / "missing.jsonl")
    with pytest.raises(SessionError, match="is a directory"):
        load_session(tmp_path)
    (tmp_path / "bin.jsonl").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(SessionError, match="not UTF-8"):
        load_session(tmp_path / "bin.jsonl")


def test_session_exchanges_decode_the_chunks() -> None:
    session = Session(Header("ms2000", "ms2000", LINE), (Chunk(0, RX, b"/\r"), Chunk(0.005, TX, b"N\r\n")))
    [exchange] = session.exchanges()
    assert isinstance(exchange, Exchange) and exchange.reply == b"N\r\n"


def test_a_long_session_is_checked_and_read_again_in_constant_memory(tmp_path: Path) -> None:
    """Before: the file was read whole and every event held at once (and anything under 256 MiB
    was taken: gigabytes of objects); now memory does not grow with the file."""
    path = tmp_path / "long.jsonl"
    requests = 20_000
    with path.open("w") as out:
        out.write(HEADER + "\n")
        for i in range(requests):
            out.write(json.dumps({"t": i * 0.01, "dir": "rx", "hex": "2f 0d"}) + "\n")
            out.write(json.dumps({"t": i * 0.01 + 0.005, "dir": "tx", "hex": "4e 0d 0a"}) + "\n")
        out.write('{"t": 300, "dir": "end"}\n')
    tracemalloc.start()
    try:
        session = load_session(path)
        count = sum(1 for _ in session.events)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert session.complete and count == 2 * requests
    assert peak < 2e6, f"{peak / 1e6:.1f} MB held"
