"""DLED, the two-channel current LED driver (§9.8), on profile `ms2000-dled`: TV-185, TV-186."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest

from tests.conformance.ms2000.conftest import ACK, Host

#: longest wait for the next `led` event (s)
EVENT_TIMEOUT = 2.0


@pytest.fixture
def dled(connect: Callable[..., Host]) -> Host:
    return connect("ms2000-dled")


def test_tv_185_brightness_limited_by_maximum(dled: Host) -> None:
    """TV-185 (MS-LED-4): `LED X` above the channel maximum `LED R` reads back as the maximum;
    `BU X` lists `DLED`."""
    dled.run([(b"LED R=10\r", ACK), (b"LED X=50\r", ACK), (b"LED X?\r", b"X=10 :A\r\n")])
    assert b"DLED" in dled.reply(b"BU X\r")[:-2].split(b"\r")


def led_events(dled: Host, count: int) -> Iterator[dict[str, Any]]:
    """The next `count` `led` events (the subscription must precede what causes them)."""
    seen = 0
    for event in dled.target.ctl().events(timeout=EVENT_TIMEOUT):
        if event["ev"] == "led":
            yield event
            seen += 1
            if seen == count:
                return
    raise AssertionError(f"only {seen} of {count} led events")


@pytest.mark.control
def test_tv_186_in0_modes_20_and_21(dled: Host) -> None:
    """TV-186 (MS-LED-5): in mode 20 a pulse lights both channels for `RT Y` = 50 ms; in mode 21
    pulses light X, then Y, then X."""
    dled.run([(b"LED X=50 Y=50\r", ACK), (b"TTL X=20\r", ACK), (b"RT Y=50\r", ACK)])
    assert dled.get("led")["x"] == 0
    dled.target.ctl().subscribe("dut")
    dled.input("ttl_in0", pulse_ms=5)
    on, off = led_events(dled, 2)
    assert (on["x"], on["y"], off["x"], off["y"]) == (50, 50, 0, 0)
    assert off["t"] - on["t"] == pytest.approx(0.050, abs=0.001)
    dled.ask(b"TTL X=21\r", ACK)
    lit = []
    for _ in range(3):
        dled.input("ttl_in0", pulse_ms=5)
        on, off = led_events(dled, 2)
        lit.append((on["x"], on["y"]))
        assert (off["x"], off["y"]) == (0, 0)
    assert lit == [(50, 0), (0, 50), (50, 0)]
