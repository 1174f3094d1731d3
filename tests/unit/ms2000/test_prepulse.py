"""PREPULSE (MS-91): OUT0 mode 8, emulated as mode 2."""

from __future__ import annotations

from collections.abc import Callable

from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"
#: the test vectors' test-only profile (Appendix A.2)
ALL_MODULES = "ms2000-all-modules"


def test_mode_8_needs_the_module(make: Callable[..., Harness]) -> None:
    """MS-91, MS-118: without PREPULSE `TTL Y=8` is a mode of an absent module."""
    assert make().cmd("TTL Y=8") == b":N-4\r\n"


def test_mode_8_pulses_after_each_move(make: Callable[..., Harness]) -> None:
    """MS-91 [choice]: the pre-pulse is emulated as mode 2, one `RT Y` ms pulse per move."""
    ms = make(ALL_MODULES)
    assert ms.cmd("TTL Y=8") == ACK
    assert ms.cmd("TTL Y?") == b":A Y=8\r\n"
    ms.take_events()
    ms.cmd("M X=100")
    ms.idle()
    ms.wait(0.1)
    assert [e["level"] for e in ms.take_events("ttl_out0")] == [1, 0]
    assert ms.cmd("BU X").rstrip(b"\r\n").split(b"\r")[-1] == b"PREPULSE"
