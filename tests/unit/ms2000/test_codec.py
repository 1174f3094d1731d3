"""protocols.ms2000: command words, argument grammar, reply shapes, number formats, low-level frames."""

from __future__ import annotations

import pytest

from protocols import ms2000 as p
from protocols.ms2000 import Item, Kind, Shape


@pytest.mark.parametrize(
    ("word", "key"),
    [
        ("MOVE", "M"),
        ("m", "M"),
        ("movrel", "R"),
        ("MOVEREL", "R"),
        ("MOTOCTRL", "MC"),
        ("ttl", "TTL"),
        ("\\", "\\"),
    ],
)
def test_lookup_long_short_alias_case_insensitive_ms10_ms19(word: str, key: str) -> None:
    spec = p.lookup(word)
    assert spec is not None and spec.key == key


def test_lookup_unknown_and_module_owner_ms118() -> None:
    assert p.lookup("FOO") is None
    assert p.lookup("LD").modules == ("RING BUFFER",)
    assert p.lookup("AL").modules == ("CRISP", "AUTOFOCUS")
    assert p.lookup("W").is_base


def test_split_command_special_first_characters_ms19_ms20() -> None:
    assert p.split_command("!X").spec.key == "!"
    assert p.parse_items(p.split_command("!X").args) == [Item(Kind.BARE, "X", None, "X")]
    assert p.split_command("\\ junk").spec.key == "\\"
    assert p.split_command("  \\junk").spec.key == "\\"
    assert p.split_command("FOO X=1").spec is None
    assert p.split_command("V\x01").spec is None


def test_lf_and_tab_are_whitespace_ms7() -> None:
    line = p.split_command("\nW\tX")
    assert line.spec.key == "W"
    assert [i.letter for i in p.parse_items(line.args)] == ["X"]
    assert p.is_blank("\n \t")
    assert not p.is_blank("\x0b")


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (
            "X=5 Y? Z+ F- T",
            [("=", "X", 5.0), ("?", "Y", None), ("+", "Z", None), ("-", "F", None), ("", "T", None)],
        ),
        ("VX=4.690000 VY=4.690000 ", [("=", "X", 4.69), ("=", "Y", 4.69)]),
        ("ACX=25.000000", [("=", "X", 25.0)]),
        ("Y = 0.5", [("=", "Y", 0.5)]),
        ("X= Y=5", [("=", "X", None), ("=", "Y", 5.0)]),
        ("X=abc", [("=", "X", None)]),
        (
            "X=1e3 Y=.5e1 Z=-9.0 F=1000.",
            [("=", "X", 1000.0), ("=", "Y", 5.0), ("=", "Z", -9.0), ("=", "F", 1000.0)],
        ),
        ("Y=9 55", [("=", "Y", 9.0), ("#", None, 55.0)]),
        ("x? y=2", [("?", "X", None), ("=", "Y", 2.0)]),
        ("5=3 %%", [("!", None, None), ("!", None, None)]),
    ],
)
def test_items_grammar_ms21_to_ms26(args: str, expected: list[tuple[str, str | None, float | None]]) -> None:
    got = [(i.kind.value, i.letter, i.value) for i in p.parse_items(args)]
    assert got == expected


@pytest.mark.parametrize(
    ("value", "prefix", "whole"),
    [
        ("50?", 50.0, None),
        ("1.5abc", 1.5, None),
        ("abc", None, None),
        ("-.5e", -0.5, None),
        ("2e3x", 2000.0, None),
        ("1e999", None, None),  # not finite: no number
        ("+7", 7.0, 7.0),
        ("", None, None),
    ],
)
def test_set_value_is_its_numeric_prefix_ms25(value: str, prefix: float | None, whole: float | None) -> None:
    assert p.parse_items(f"X={value}")[0].value == prefix
    assert p.parse_items(f"X={value}", numeric_prefix=False)[0].value == whole


def test_command_line_encoder() -> None:
    assert p.command_line("M", {"X": 1000, "Y": -505}) == b"M X=1000 Y=-505\r"
    assert p.command_line("S", {"X": 4.69, "Y": None}) == b"S X=4.690000 Y?\r"
    assert p.command_line("RS", ["X+"]) == b"RS X+\r"
    assert p.format_command("M", {"X": 1000.0, "Y": -0.5}) == "M X=1000 Y=-0.500000"
    assert p.format_command("W", ["X", "Y"]) == "W X Y"


def test_error_table_ms39() -> None:
    assert p.error_text(p.ErrorCode.OUT_OF_RANGE) == "parameter out of range"
    assert p.error_text(21) == "serial command halted by HALT"
    assert p.error_text(9) == "error"


@pytest.mark.parametrize(
    ("value", "decimals", "text"),
    [
        (1.23456789, 6, "1.234568"),
        (4.69, 6, "4.690000"),
        (-0.0000001, 6, "0.000000"),
        (0.0000005, 6, "0.000001"),
        (-0.0000005, 6, "-0.000001"),
        (-110, 3, "-110.000"),
        (2.5, 0, "3"),
        (-2.5, 0, "-3"),
        (-0.4, 0, "0"),
        (1000.0881, 1, "1000.1"),
    ],
)
def test_fixed_half_away_no_minus_zero_ms47_ms48(value: float, decimals: int, text: str) -> None:
    assert p.fixed(value, decimals) == text


def test_where_format_ms47() -> None:
    assert p.where(12344.92) == "12345"
    assert p.where(-504.8903, 3) == "-504.890"
    assert p.where(-0.2) == "0"


@pytest.mark.parametrize(
    ("shape", "text"),
    [
        (Shape.ACK, ":A"),
        (Shape.A_AXIS, ":A X=5.145600 Y=5.145600"),
        (Shape.COLON_AXIS_A, ":X=5.145600 Y=5.145600 A"),
        (Shape.AXIS_COLON_A, "X=5.145600 Y=5.145600 :A"),
        (Shape.A_LIST, ":A 5.145600 5.145600"),
        (Shape.BARE, "5.145600 5.145600"),
    ],
)
def test_reply_shapes_section3(shape: Shape, text: str) -> None:
    assert p.format_items(shape, [("X", "5.145600"), ("Y", "5.145600")]) == text


def test_trailing_space_applies_to_value_shapes_only_ms38() -> None:
    assert p.format_items(Shape.A_LIST, [("X", "0")], trailing_space=True) == ":A 0 "
    assert p.format_items(Shape.AXIS_COLON_A, [("X", "0")], trailing_space=True) == "X=0 :A"
    assert p.format_items(Shape.BUSY_CHAR, [("", "N")], trailing_space=True) == "N"


def test_query_shapes_and_overrides_ms35_ms36_ms37() -> None:
    assert p.query_shape("OS") is Shape.A_AXIS
    assert p.query_shape("OS", {"OS": "colon_axis_A"}) is Shape.COLON_AXIS_A
    assert p.query_shape("B") is Shape.COLON_AXIS_A
    assert p.query_shape("LED") is Shape.AXIS_COLON_A
    assert p.query_shape("W") is Shape.A_LIST


def test_frames_and_terminators_ms14_ms15_ms16() -> None:
    assert p.frame([b":A"]) == b":A\r\n"
    assert p.frame([b"a", b"b"]) == b"a\rb\r\n"
    assert p.frame([b"a", b"b"], cr_only=True) == b"a\rb\r"
    assert p.split_lines(b"85\r87\r:A\r\n") == [b"85", b"87", b":A"]
    assert p.error_reply(p.ErrorCode.HALTED) == ":N-21"


@pytest.mark.parametrize(
    ("line", "kind", "detail"),
    [
        (b":A\r\n", p.ReplyKind.ACK, None),
        (b":A \r\n", p.ReplyKind.ACK, None),
        (b":N-21\r\n", p.ReplyKind.ERROR, 21),
        (b"N\r\n", p.ReplyKind.BUSY, None),
        (b"\n:A X=7.680000\r", p.ReplyKind.VALUES, ("X", "7.680000")),
        (b":X=0.040000 A\r\n", p.ReplyKind.VALUES, ("X", "0.040000")),
        (b"X=10 :A\r\n", p.ReplyKind.VALUES, ("X", "10")),
        (b":A JS_FAST=100 JS_SLOW=5\r\n", p.ReplyKind.VALUES, ("JS_SLOW", "5")),
        (b"STD_XYZ\r\n", p.ReplyKind.TEXT, None),
    ],
)
def test_parse_reply(line: bytes, kind: p.ReplyKind, detail: object) -> None:
    reply = p.parse_reply(line)
    assert reply.kind is kind
    if kind is p.ReplyKind.ERROR:
        assert reply.code == detail
    elif isinstance(detail, tuple):
        assert reply.value(detail[0]) == detail[1]


def test_parse_reply_list() -> None:
    assert p.parse_reply(b":A 1000 -505 0\r\n").numbers == ("1000", "-505", "0")


@pytest.mark.parametrize(
    ("line", "kind", "values", "numbers"),
    [
        (":A Version: USB-9.2k ", p.ReplyKind.VALUES, (), ("Version:", "USB-9.2k")),
        (":A X=abc", p.ReplyKind.VALUES, (), ("X=abc",)),
        (":X=1 Y A", p.ReplyKind.TEXT, (), ()),
        ("85\r87\r:A", p.ReplyKind.TEXT, (), ()),
    ],
)
def test_parse_reply_values_only_when_every_item_is_name_number(
    line: str, kind: p.ReplyKind, values: tuple[tuple[str, str], ...], numbers: tuple[str, ...]
) -> None:
    reply = p.parse_reply(line)
    assert (reply.kind, reply.values, reply.numbers) == (kind, values, numbers)


def test_parse_info_splits_rows_at_column_33_ms106() -> None:
    row = f"{'Axis Name    :  X':<{p.INFO_LEFT_WIDTH}}Limits Status: U"
    speed = f"{'Max Speed    :  7.680000 (mm/s)':<{p.INFO_LEFT_WIDTH}}Ramp Time    :        50 (ms)[AC]"
    assert p.parse_info(f"{row}\r{speed}") == {
        "Axis Name": "X",
        "Limits Status": "U",
        "Max Speed": "7.680000 (mm/s)",
        "Ramp Time": "50 (ms)[AC]",
    }


@pytest.mark.parametrize(
    ("value", "raw"), [(-12345, b"\xc7\xcf\xff"), (100000, b"\xa0\x86\x01"), (1000, b"\xe8\x03\x00")]
)
def test_int24_lsb_first_twos_complement_ms120(value: int, raw: bytes) -> None:
    assert p.encode_int24(value) == raw
    assert p.decode_int24(raw) == value


def test_int24_wraps_ms120() -> None:
    assert p.decode_int24(p.encode_int24(p.INT24_MAX + 1)) == -(p.INT24_MAX + 1)


def test_ll_frame_encoder_matches_spec_examples_ms120() -> None:
    assert p.encode_ll_frame(0x18, p.LLCommand.POSITION) == b"\x18\x61\x03\x3a"
    assert p.encode_ll_frame(0x18, p.LLCommand.BUSY) == b"\x18\x3f\x00\x3a"
    assert p.encode_ll_frame(0x18, p.LLCommand.STATUS) == b"\x18\x7e\x01\x3a"
    assert p.encode_ll_frame(0x18, p.LLCommand.POSITION_STATUS) == b"\x18\x6c\x03\x3a"
    assert p.encode_ll_frame(0x18, p.LLCommand.MOVE_TO, 100000) == b"\x18\x54\x03\xa0\x86\x01\x3a"


def _decode(data: bytes, ids: tuple[int, ...] = (0x18,)) -> list[p.LLFrame]:
    decoder = p.LLFrameDecoder(ids)
    frames = [decoder.feed(b) for b in data]
    return [f for f in frames if f is not None]


def test_ll_decoder_frames_ms120_ms123() -> None:
    frames = _decode(b"\x18\x54\x03\xa0\x86\x01\x3a\x18\x4b\x3a\x18\x61\x03\x99\x3a\x20\x61\x03\x3a")
    assert [(f.axis_id, f.command, f.data, f.known) for f in frames[:3]] == [
        (0x18, ord("T"), b"\xa0\x86\x01", True),
        (0x18, ord("K"), b"", True),
        (0x18, ord("a"), b"", True),
    ]
    assert (frames[3].axis_id, frames[3].known) == (0x20, False)


def test_ll_decoder_data_may_contain_terminator_byte() -> None:
    frames = _decode(b"\x18\x44\x03\x3a\x00\x00\x3a")
    assert frames[0].known and frames[0].data == b"\x3a\x00\x00"


def test_ll_decoder_unknown_command_consumed_to_terminator_ms123() -> None:
    frames = _decode(b"\x18\x01\x02\x03\x3a\x18\x3f\x00\x3a")
    assert [(f.command, f.known) for f in frames] == [(1, False), (ord("?"), True)]


def test_summaries() -> None:
    assert p.summarize_line(b"M X=1000") == "M X=1000 [MOVE]"
    assert p.summarize_line(b"  ") == "blank line"
    assert p.summarize_line(b"FOO") == "FOO [?]"
    assert p.shown(b":A\r\n") == ":A\\r\\n"
    assert p.shown(b"\x18\x61\x03\x3a") == "binary 18 61 03 3a"
