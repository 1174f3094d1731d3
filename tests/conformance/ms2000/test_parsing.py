"""Command lines, items and errors (§2, §4): TV-1…TV-10, TV-13, TV-15, TV-21…TV-25, TV-115, TV-215."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import pytest

from tests.conformance.ms2000.conftest import ACK, SILENT, VERSION, Host, Step

VECTORS = [
    pytest.param([(b"V\r", VERSION)], id="tv001_version", marks=pytest.mark.smoke),
    pytest.param([(b"v\r", VERSION), (b"s x?\r", b":A X=5.145600\r\n")], id="tv002_case_insensitive"),
    pytest.param([(b"\r", b":N-1\r\n")], id="tv003_empty_line", marks=pytest.mark.smoke),
    pytest.param([(b"V\r\nCD\r", VERSION + b"Mar 14 2016:17:32:08\r\n")], id="tv005_crlf_host"),
    pytest.param([(b"\n\r", b":N-1\r\n")], id="tv006_lf_cr_is_blank"),
    pytest.param(
        [(b"A" * 300 + b"\r", b":N-6\r\n"), (b"/\r", b"N\r\n"), (b"W X" + b" " * 400 + b"\r", b":N-6\r\n")],
        id="tv007_overlong_line",
        marks=pytest.mark.smoke,
    ),
    pytest.param(
        [(b"FOO X=1\r", b":N-1\r\n"), (b"MOVEREL X=0\r", ACK), (b"!X\r", ACK)], id="tv008_words_and_splitting"
    ),
    pytest.param([(b"V\x01\r", b":N-1\r\n")], id="tv009_control_byte_in_word"),
    pytest.param([(b"/\rV\r", b"N\r\n" + VERSION)], id="tv010_two_lines_one_write"),
    pytest.param(
        [(b"S VX=4.690000 VY=4.690000 \r", ACK), (b"S Y? X?\r", b":A X=4.690000 Y=4.690000\r\n")],
        id="tv013_prefixed_keys_hardware_order",
    ),
    pytest.param([(b"S Y = 0.5\r", ACK), (b"S Y?\r", b":A Y=0.500000\r\n")], id="tv015_spaces_around_equals"),
    pytest.param(
        [(b"S F?\r", b":N-2\r\n"), (b"TTL Q=1\r", b":N-2\r\n"), (b"TTL R?\r", b":N-2\r\n")],
        id="tv021_letters_not_accepted",
    ),
    pytest.param(
        [(b"S Q=0\r", b":N-2\r\n"), (b"S X=1 Y=0\r", b":N-4\r\n"), (b"S X?\r", b":A X=5.145600\r\n")],
        id="tv022_lowest_code_wins",
    ),
    pytest.param([(b"S X=1 X=2\r", ACK), (b"S X?\r", b":A X=2.000000\r\n")], id="tv023_last_item_wins"),
    pytest.param(
        [
            (b"W Q\r", b":N-2\r\n"),
            (b"W\r", b":N-3\r\n"),
            (b"M X=1000 Q=5\r", b":N-2\r\n"),
            (b"W X\r", b":A 0\r\n"),
        ],
        id="tv024_bad_letter_and_missing_items",
    ),
    pytest.param(
        [(b"SL X=-50 Y=-50 Z?\r", b":A Z=-110.000\r\n"), (b"SL X? Y?\r", b":A X=-50.000 Y=-50.000\r\n")],
        id="tv025_sets_and_queries_mixed",
    ),
    pytest.param(
        [(b"AR\r", b":N-1\r\n"), (b"CCB Z=1\r", b":N-1\r\n"), (b"WRDAC X=1\r", b":N-1\r\n")],
        id="tv115_absent_module_commands",
    ),
    pytest.param([(b"SI X=0\r", b":N-1\r\n")], id="tv215_search_index_absent"),
]


@pytest.mark.parametrize("steps", VECTORS)
def test_tv_exchanges(ms: Host, steps: Sequence[Step]) -> None:
    """Each case is one test vector on the default profile: every reply byte for byte (MS-6…MS-31,
    MS-39, MS-40, MS-118; the rules of each vector are listed in the reference's §10 table)."""
    ms.run(steps)


def test_tv_004_empty_line_ignored_by_knob(connect: Callable[..., Host]) -> None:
    """TV-4 (MS-8): with `empty_line_reply: ignore` a blank line produces no byte at all."""
    host = connect(overrides={"knobs": {"empty_line_reply": "ignore"}})
    host.run([(b"\r", b""), SILENT, (b"/\r", b"N\r\n")])


def test_failed_validation_applies_nothing(ms: Host) -> None:
    """Beside TV-22 (MS-27): a failing item stops the whole command, its valid items included."""
    ms.run([(b"S X=1 Q=0\r", b":N-2\r\n"), (b"S X?\r", b":A X=5.145600\r\n")])


@pytest.mark.parametrize(
    ("line", "reply"),
    [
        (b"S 5=3\r", b":N-6\r\n"),  # an item without a key letter (MS-21)
        (b"M X=abc\r", ACK),  # not a number: missing, 0 (MS-25)
        (b"MOTOCTRL X?\r", b":A 1\r\n"),  # alias (MS-19)
        (b"\t/\r", b"N\r\n"),  # TAB is whitespace (MS-7)
        (b"@X=0\r", ACK),  # split after `@` (MS-19)
    ],
)
def test_words_and_items_beyond_the_vectors(ms: Host, line: bytes, reply: bytes) -> None:
    """Beside TV-8 and TV-30: an alias, a split word, a malformed item, a non-numeric value."""
    ms.ask(line, reply)


@pytest.mark.parametrize(
    ("steps"),
    [
        # a host in the field sends a query mark after the value and expects the intensity set
        [(b"LED X=50? \r", ACK), (b"LED X?\r", b"X=50 :A\r\n")],
        [(b"S X=1.5abc\r", ACK), (b"S X?\r", b":A X=1.500000\r\n")],
        [(b"S X=2.5e-1x\r", ACK), (b"S X?\r", b":A X=0.250000\r\n")],
        [(b"S X=-.5e\r", b":N-4\r\n")],  # -0.5: out of range like `S X=-0.5`
    ],
)
def test_ms25_value_is_its_numeric_prefix(ms: Host, steps: list[tuple[bytes, bytes]]) -> None:
    """MS-25 (field correction): the firmware reads a value as C's `strtod` does, the number it
    starts with; `abc` has none and reads as 0 (TV-30 still holds)."""
    ms.run(steps)


def test_ms25_whole_number_values_by_knob(connect: Callable[..., Host]) -> None:
    """MS-25, knob `number_values: whole`: only a value that is a number as a whole counts; `50?`
    is then missing, which is 0."""
    host = connect(overrides={"knobs": {"number_values": "whole"}})
    host.run([(b"LED X=50? \r", ACK), (b"LED X?\r", b"X=0 :A\r\n")])
