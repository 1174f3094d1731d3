"""DLED, the two-channel current LED driver (§9.8), on profile `ms2000-dled`: TV-185, TV-186."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest

from tests.conformance.ms2000.conftest import ACK, EXACT_S, Host

#: longest wait for the next `led` event (s)
EVENT_TIMEOUT = 2.0


@pytest.fixture
def dled(connect: Callable[..., Host]) -> Host:
    return connect("ms2000-dled")


@pytest.mark.smoke
def test_tv_185_brightness_limited_by_maximum(dled: Host) -> None:
    """TV-185 (MS-LED-4): `LED X` above the channel maximum `LED R` reads back as the maximum,
    whichever item of the command comes first (`T` is Y's maximum); `BU X` lists `DLED`."""
    dled.run(
        [
            (b"LED R=10\r", ACK),
            (b"LED X=50\r", ACK),
            (b"LED X?\r", b"X=10 :A\r\n"),
            (b"LED X=50 R=100\r", ACK),
            (b"LED X? R?\r", b"X=50 R=100 :A\r\n"),
            (b"LED Y=80 T=30\r", ACK),
            (b"LED X? Y? R? T?\r", b"X=50 Y=30 T=30 R=100 :A\r\n"),
        ]
    )
    assert b"DLED" in dled.reply(b"BU X\r")[:-2].split(b"\r")


@pytest.mark.control
def test_tv_185_levels_light_the_channels(dled: Host) -> None:
    """TV-185 (MS-LED-4): outside the IN0 modes 20–23 the levels light the channels steadily, X at
    50 % drawing 450 mA."""
    dled.run([(b"LED X=50 Y=80 T=30\r", ACK)])
    led = dled.get("led")
    assert (led["x"], led["y"]) == (50, 30)
    assert led["x_ma"] == pytest.approx(450.0)


def lit(dled: Host) -> tuple[int, int]:
    led = dled.get("led")
    return led["x"], led["y"]


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
    """TV-186 (MS-LED-5): the channels, lit steadily before, are dark in mode 20 until a pulse lights
    both for `RT Y` = 50 ms (an edge while lit starts the time again); in mode 21 pulses light X,
    then Y, then X, skipping a channel at 0 %; back in mode 0 they are lit steadily. Event times
    are exact device times."""
    dled.ask(b"LED X=50 Y=50\r", ACK)
    assert lit(dled) == (50, 50)
    dled.run([(b"TTL X=20\r", ACK), (b"RT Y=50\r", ACK)])
    assert lit(dled) == (0, 0)
    ctl = dled.target.ctl()
    ctl.subscribe("dut")
    dled.input("ttl_in0", pulse_ms=5)
    on, off = led_events(dled, 2)
    assert (on["x"], on["y"], off["x"], off["y"]) == (50, 50, 0, 0)
    assert off["t"] - on["t"] == pytest.approx(0.050, abs=EXACT_S)
    ctl.pause()
    try:
        dled.input("ttl_in0", pulse_ms=5)
        ctl.step(0.030)
        dled.input("ttl_in0", pulse_ms=5)  # lit already: no event, the 50 ms start again
        ctl.step(0.1)
    finally:
        ctl.resume()
    on, off = led_events(dled, 2)
    assert off["t"] - on["t"] == pytest.approx(0.080, abs=EXACT_S)
    dled.ask(b"TTL X=21\r", ACK)
    seen = []
    for _ in range(3):
        dled.input("ttl_in0", pulse_ms=5)
        on, off = led_events(dled, 2)
        seen.append((on["x"], on["y"]))
        assert (off["x"], off["y"]) == (0, 0)
    assert seen == [(50, 0), (0, 50), (50, 0)]
    dled.ask(b"LED Y=0\r", ACK)
    for _ in range(2):
        dled.input("ttl_in0", pulse_ms=5)
        on, _ = led_events(dled, 2)
        assert (on["x"], on["y"]) == (50, 0)
    dled.ask(b"TTL X=0\r", ACK)
    assert lit(dled) == (50, 0)
