"""protocols.mp285: command encoding/decoding, replies, status block, units, the frame parser."""

from __future__ import annotations

import itertools

import pytest

from protocols import mp285 as p
from protocols.mp285 import (
    BadFrame,
    BufferOverrun,
    CtrlC,
    ErrorCode,
    Frame,
    FrameParser,
    ParseState,
    StatusBlock,
    StrayTerminator,
    Vector,
)

DUMP_A = bytes.fromhex(
    "40 00 02 04 07 00 63 00 63 00 14 00 88 13 01 78 70 17 10 27 50 00 00 00 19 00 04 00 C8 00 54 01"
)

ENCODINGS = [
    (p.GetPosition(), "63 0D"),
    (p.Move(1200, -40, 0), "6D B0 04 00 00 D8 FF FF FF 00 00 00 00 0D"),
    (p.SetVelocity(0x00C8), "56 C8 00 0D"),
    (p.SetVelocity.of(777, high=True), "56 09 83 0D"),
    (p.SetOrigin(), "6F 0D"),
    (p.Absolute(), "61 0D"),
    (p.Relative(), "62 0D"),
    (p.Interrupt(), "03"),
    (p.Refresh(), "6E 0D"),
    (p.Reset(), "72 0D"),
    (p.GetStatus(), "73 0D"),
    (
        p.Download(1, (Vector.move(250, 0, -250), Vector.pause())),
        "64 01 02 D0 07 00 00 FA 00 00 00 00 00 00 00 06 FF FF FF" + " 00" * 16 + " 0D",
    ),
    (p.Execute(3), "6B 03 0D"),
    (p.Upload(10), "75 0A 0D"),
    (p.Continue(), "65 0D"),
]


@pytest.mark.parametrize(("command", "wire"), ENCODINGS, ids=[type(c).__name__ for c, _ in ENCODINGS])
def test_every_command_encodes_and_parses_back(command: p.Command, wire: str) -> None:
    """MP-13, MP-11 (LSB first), MP-16/MP-17 (16-byte vectors, descriptor D0 07 00 00)."""
    data = command.encode()
    assert data.hex(" ").upper() == wire
    parser = FrameParser()
    items = parser.feed(data)
    if isinstance(command, p.Interrupt):
        assert items == [CtrlC()]
    else:
        assert items == [Frame(command, data)]
    assert parser.state is ParseState.COMMAND


def test_command_table_matches_the_corrected_quick_reference() -> None:
    """MP-13, MP-14: `u` is 75, `m` 6D; MP-15: `r` replies nothing; frame and reply lengths."""
    table = {chr(b): (s.frame_length, s.reply) for b, s in p.COMMANDS.items()}
    assert table == {
        "c": (2, 13),
        "m": (14, 1),
        "V": (4, 1),
        "o": (2, 1),
        "a": (2, 1),
        "b": (2, 1),
        "n": (2, 1),
        "r": (2, 0),
        "s": (2, 33),
        "d": (None, 1),
        "k": (3, 1),
        "u": (3, None),
        "e": (2, 1),
    }
    assert p.reply_length(p.GetStatus()) == 33
    assert p.reply_length(p.Upload(1)) is None


def test_velocity_word() -> None:
    """MP-37: bit 15 resolution, bits 14-0 µm/s."""
    assert p.Velocity(200).word == 0x00C8
    assert p.Velocity.from_word(0x851E) == p.Velocity(1310, True)
    assert p.SetVelocity(0x83E8).velocity == p.Velocity(1000, True)
    with pytest.raises(ValueError):
        p.Velocity(0x8000)


def test_speed_limits_clamp_ms38_ms39() -> None:
    """MP-38, MP-39: limits per model and resolution; a faster `V` speed is reduced to the limit."""
    mp285a = p.SpeedLimits.of_model("mp285a")
    assert (mp285a.limit(False), mp285a.limit(True)) == (3000, 1310)
    assert p.SpeedLimits.of_model("mp285").clamp(p.Velocity(7000)) == p.Velocity(6550)
    assert mp285a.clamp(p.Velocity(2000, True)) == p.Velocity(1310, True)
    assert mp285a.clamp(p.Velocity(200)) == p.Velocity(200)


def test_position_and_program_replies() -> None:
    """MP-27, MP-72: 13-byte position reply; `u` reply n + vectors + CR, `00 0D` when empty."""
    reply = p.encode_position(-4_596_737, -4_576_262, -16_148_393)
    assert reply.hex(" ").upper() == "FF DB B9 FF FA 2B BA FF 57 98 09 FF 0D"
    assert p.decode_position(reply) == (-4_596_737, -4_576_262, -16_148_393)
    vectors = (Vector.move(1, 2, 3), Vector(0xD0070000, 4, 5, 6))
    assert p.decode_program(p.encode_program(vectors)) == vectors
    assert p.encode_program(()) == b"\x00\r"
    with pytest.raises(ValueError):
        p.decode_position(b"\r")
    with pytest.raises(ValueError):
        p.decode_program(b"\x01\r")


def test_vector_descriptor_is_wire_order() -> None:
    """MP-17: the bytes D0 07 00 00 are a move vector; 00 00 07 D0 is not."""
    assert Vector.unpack(bytes.fromhex("D0 07 00 00") + bytes(12)).is_move
    odd = Vector.unpack(bytes.fromhex("00 00 07 D0") + bytes(12))
    assert not odd.is_move and not odd.is_pause
    assert Vector.pause().pack() == bytes(16)


def test_status_block_round_trip_and_fields() -> None:
    """MP-60, MP-11: the real dump A decodes to VERSION 340, STEP 25/4, XSPEED 200 low."""
    block = StatusBlock.unpack(DUMP_A + b"\r")
    assert (block.version, block.step_div, block.step_mul, block.xspeed) == (340, 25, 4, 0x00C8)
    assert (block.roe_vari, block.flags, block.flags_2, block.udirz) == (7, 0x40, 0x78, 4)
    assert block.velocity == p.Velocity(200)
    assert not block.roe_negative and not block.step_mode_high and block.setup_number == 0
    assert block.pack() == DUMP_A
    assert block.reply() == DUMP_A + b"\r"
    assert "VERSION 3.40" in block.describe()
    with pytest.raises(ValueError):
        StatusBlock.unpack(DUMP_A[:-1])


def test_errors() -> None:
    """MP-19: digits, the OR rule, names."""
    assert p.error_reply(ErrorCode.BAD_COMMAND) == b"4\r"
    assert p.combine_errors(ErrorCode.MOVE_INTERRUPTED, ErrorCode.BAD_COMMAND) == 0x3C
    assert p.error_text(0x3C) == "move interrupted + bad command"
    assert p.error_text(0x30) == "SP overrun"
    assert p.error_text(0x3B) == "move interrupted + '3'"
    assert p.error_text(0x41) == "unknown error 41"
    assert all(p.is_error_code(c) for c in b"012489:;<")
    assert not p.is_error_code(0x33)


def test_units() -> None:
    """MP-28, MP-63: factors per device type, STEP fields in both formats."""
    assert p.axis_factors("mp285") == (25, 25, 25)
    assert p.axis_factors("mt800", 50) == (20, 20, 50)
    assert p.usteps_to_um(250, 25) == 10.0
    assert p.um_to_usteps(-0.02, 25) == -1  # half away from zero
    assert p.step_fields(25, "mp285") == (25, 4)
    assert p.step_fields(20, "mp285") == (20, 5)
    assert p.step_fields(25, "mp285a") == (400, 400)
    assert p.step_fields(20, "mp285a") == (500, 500)


# ---- parser ----------------------------------------------------------------------------------------


def parse_all(data: bytes, size: int = 64) -> list[p.Item]:
    return FrameParser(size).feed(data)


@pytest.mark.parametrize(
    ("data", "items"),
    [
        (b"\x03", [CtrlC()]),
        (b"\r\n", [StrayTerminator(0x0D), StrayTerminator(0x0A)]),
        (b"C\r", [BadFrame(0x34)]),  # MP-21
        (b"xyz\r", [BadFrame(0x34)]),
        (b"cc\r", [BadFrame(0x34)]),  # MP-22
        (b"c\n", []),
        (b"d\x01\x00\r", [BadFrame(0x34)]),  # MP-67: n = 0, length unknown
        (b"d\x01\x64" + bytes(20) + b"\r", [BadFrame(0x34)]),
        (b"x\x03\r", [BadFrame(0x34)]),  # MP-24: ^C is dropped while discarding
    ],
)
def test_parser_items(data: bytes, items: list) -> None:
    assert parse_all(data) == items


def test_parser_payload_may_hold_cr_lf_and_ctrl_c() -> None:
    """MP-8, MP-9: the parser never looks for CR inside a frame."""
    frame = bytes.fromhex("6D 0D 0A 03 00 0D 0D 00 00 0D FF FF FF 0D")
    (item,) = parse_all(frame)
    assert isinstance(item, Frame)
    assert item.command == p.Move(0x00030A0D, 3341, -243)


def test_parser_eight_byte_longs() -> None:
    """MP-26: a discarded 0D ends DISCARDING early and the rest is a second bad frame."""
    data = bytes.fromhex("6D FA 00 00 00 00 00 00 00 F4 01 00 00 00 00 00 00 0D 00 00 00 00 00 00 00 0D")
    assert parse_all(data) == [BadFrame(0x34), BadFrame(0x34)]


def test_parser_buffer_overrun() -> None:
    """MP-23: `32` at the 65th byte; each further run of 65 another; the CR then owes nothing."""
    parser = FrameParser(64)
    items = [parser.feed_byte(b) for b in b"q" + b"A" * 64]
    assert items[-1] == BufferOverrun() and all(i is None for i in items[:-1])
    assert [parser.feed_byte(b) for b in b"A" * 65][-1] == BufferOverrun()
    assert parser.feed_byte(0x0D) == BadFrame(None)
    long_download = p.Download(1, (Vector.pause(),) * 99).encode()
    assert len(long_download) == 1588
    assert isinstance(FrameParser(64).feed(long_download)[0], Frame)  # well-formed frames never overrun


def test_parser_framing_errors() -> None:
    """MP-6 item 4, MP-24: a framing-error character is never data; '1' replaces a pending '4'."""
    parser = FrameParser()
    assert parser.feed_byte(0x63, framing_error=True) is None
    assert parser.pending_error == ErrorCode.FRAME
    assert parser.feed_byte(0x0D, framing_error=True) is None  # not a clean CR
    assert parser.feed_byte(0x0D) == BadFrame(0x31)
    parser.feed(b"z")
    parser.feed_byte(0x63, framing_error=True)
    assert parser.feed_byte(0x0D) == BadFrame(0x31)
    parser.feed(b"m\x01")
    assert parser.feed_byte(0x02, framing_error=True) is None
    assert parser.state is ParseState.DISCARDING
    assert parser.feed(b"\r") == [BadFrame(0x31)]


def test_parser_state_for_the_device_model() -> None:
    """The model needs the state: command position, inside a frame, terminator position, discarding."""
    parser = FrameParser()
    parser.feed(b"V\x01")
    assert parser.state is ParseState.COLLECTING
    assert parser.command_byte == 0x56 and parser.frame_bytes == b"V\x01"
    assert not parser.expects_terminator
    parser.feed(b"\x02")
    assert parser.expects_terminator
    assert parser.abandon(None) is None
    assert parser.state is ParseState.DISCARDING
    assert parser.feed(b"\r") == [BadFrame(None)]
    parser.feed(b"m")
    parser.reset()
    assert parser.state is ParseState.COMMAND and parser.frame_bytes == b""


STREAM = (
    b"c\rs\r\x03\r\nm"
    + bytes.fromhex("0D 00 00 00 0D 0D 00 00 0D FF FF FF")
    + b"\rzz\r"
    + p.Download(2, (Vector.move(1, 2, 3),)).encode()
    + b"cc\rV\x0d\x00\r"
)


def test_parser_chunking_never_matters() -> None:
    """Every split of a mixed stream into two or three chunks gives the same items."""
    whole = parse_all(STREAM)
    assert len(whole) == 10
    for i, j in itertools.combinations(range(1, len(STREAM)), 2):
        parser = FrameParser()
        assert parser.feed(STREAM[:i]) + parser.feed(STREAM[i:j]) + parser.feed(STREAM[j:]) == whole


def test_summaries() -> None:
    """One-line traffic summaries: parser items, device bytes, replies naming their command."""
    items = p.FrameParser().feed(p.Move(1200, -40, 0).encode() + b"\x03\rz\r")
    assert [p.describe_item(item) for item in items] == [
        "m X=1200 Y=-40 Z=0 (µsteps)",
        "^C",
        "stray CR",
        "CR ending a bad frame (error '4' owed)",
    ]
    assert p.describe_item(p.FrameParser().feed(b"V\xc8\x00\r")[0]) == "V 200 µm/s low (word 00C8)"
    assert p.summarize_device(b"\r", to="a") == "reply to a: CR (done)"
    assert p.summarize_device(b"4\r", to="z") == "reply to z: error '4' bad command"
    assert p.summarize_device(p.encode_position(1, -2, 3)) == "reply: position X=1 Y=-2 Z=3 (µsteps)"
    assert p.summarize_device(b"4\r") == "error '4' bad command"
    assert p.summarize_device(b"<\r") == "error '<' move interrupted + bad command"
    assert p.summarize_device(b"\r") == "reply: CR (done)"
    assert p.summarize_device(b"=") == "reply: '=' (interrupt acknowledged)"
    assert p.summarize_device(DUMP_A + b"\r").startswith("reply: status FLAGS 40, XSPEED 200 µm/s low")
    assert p.summarize_device(p.encode_program((Vector.pause(),))) == "reply: program of 1 vector(s): pause"
    assert p.summarize_device(b"\x00\x00") == "2 byte(s): 00 00"
