"""Low-level binary mode (§8) on the model, beyond the test vectors, which run in
tests/conformance/ms2000 (TV-122…TV-128)."""

from __future__ import annotations

import pytest

from tests.unit.ms2000.conftest import Harness


@pytest.fixture
def low(ms: Harness) -> Harness:
    """X at -12345 units (as the vectors set it up), then low-level mode."""
    assert ms.cmd("H X=-12345") == b":A\r\n"
    assert ms.send(b"\xff\x42") == b""
    return ms


def test_low_level_byte_by_byte_ms120(low: Harness) -> None:
    assert low.send(b"\x18\x6c\x03\x3a\x19\x61\x03\x3a", chunk=1) == b"\xc7\xcf\xff\x0a\x00\x00\x00"


def test_low_level_step_down_joystick_on_and_motor_start_ms121(low: Harness) -> None:
    low.send(b"\x19\x2d\x00\x3a")
    low.wait(1.0)
    low.send(b"\xff\x41")
    assert low.cmd("W Y") == b":A -100\r\n"
    low.cmd("MC Y- J Y-")
    low.send(b"\xff\x42\x19\x47\x3a\x19\x4a\x00\x3a\xff\x41")
    assert low.cmd("RS Y") == b":A 10\r\n"


def test_low_level_status_bit1_always_set_ms122(low: Harness) -> None:
    low.send(b"\xff\x41")
    low.cmd("MC X-")
    assert low.send(b"\xff\x42\x18\x7e\x01\x3a") == b"\x0a"


def test_control_sequences_anywhere_and_unknown_ones_ms119(ms: Harness) -> None:
    assert ms.send(b"W \xff\x54X\r") == b":A 0\r\n"
    assert ms.send(b"W\xff\x62 X\r") == b":A 0\r\n"
    assert ms.send(b"W X\xff\xff\r") == b":A 0\r\n"


def test_entering_low_level_drops_partial_line_ms119(ms: Harness) -> None:
    assert ms.send(b"W X\xff\x42\xff\x41\r") == b":N-1\r\n"


def test_ff_reset_without_reply_ms119_ms112(ms: Harness) -> None:
    ms.cmd("H X=500")
    assert ms.send(b"\xff\x52") == b""
    assert ms.cmd("W X") == b":A 0\r\n"
