"""The MS2000 client's reply parser (MS-35 shapes, MS-39 errors), value formatting, package exports."""

from __future__ import annotations

import pytest

from protocols import clients
from protocols.clients.ms2000 import (
    Halted,
    MS2000Error,
    OutOfRange,
    Reply,
    UnknownCommand,
    format_value,
    parse_reply,
)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (":A", Reply(True)),
        (":A ", Reply(True)),
        (":A X=5.145600 Y=5.145600", Reply(True, {"X": 5.1456, "Y": 5.1456})),
        (":X=0.040000 A", Reply(True, {"X": 0.04})),
        (":X=50 Y=50 Z=50 A", Reply(True, {"X": 50, "Y": 50, "Z": 50})),
        ("X=10 Y=50 :A", Reply(True, {"X": 10, "Y": 50})),
        (":A JS_FAST=100 JS_SLOW=5", Reply(True, {"JS_FAST": 100, "JS_SLOW": 5})),
        (":A 1234 -505 0", Reply(True, items=("1234", "-505", "0"))),
        (":A 0 ", Reply(True, items=("0",))),
        (":A Version: USB-9.2k ", Reply(True, items=("Version:", "USB-9.2k"))),
        ("STD_XYZ", Reply(False, text="STD_XYZ")),
        ("N", Reply(False, text="N")),
    ],
)
def test_reply_shapes(text: str, expected: Reply) -> None:
    assert parse_reply(text) == expected


@pytest.mark.parametrize(
    ("text", "cls", "code"),
    [(":N-1", UnknownCommand, 1), (":N-4", OutOfRange, 4), (":N-21", Halted, 21), (":N-9", MS2000Error, 9)],
)
def test_errors_raise_typed_exceptions(text: str, cls: type, code: int) -> None:
    with pytest.raises(cls) as info:
        parse_reply(text, "S X=0")
    assert info.value.code == code
    assert "S X=0" in str(info.value)


def test_values_are_sent_like_the_controller_examples() -> None:
    assert format_value(1000) == "1000"
    assert format_value(-505.0) == "-505"
    assert format_value(4.69) == "4.690000"


def test_both_clients_and_their_errors_from_the_package() -> None:
    assert clients.MS2000.__module__ == "protocols.clients.ms2000"
    assert clients.Mp285.__module__ == "protocols.clients.mp285"
    assert clients.OutOfRange is OutOfRange and issubclass(clients.BadCommand, clients.Mp285Error)
    assert OutOfRange("S X=0").meaning == "parameter out of range"
