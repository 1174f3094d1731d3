"""LED DIMMER module (§9.8) and its OUT0 PWM mode: TV-16, TV-17, TV-184."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tests.conformance.ms2000.conftest import ACK, Host


@pytest.mark.smoke
@pytest.mark.control
def test_tv_016_ttl_pwm_mode_with_trailing_duty(ms: Host) -> None:
    """TV-16 (MS-24, MS-LED-3, MS-LED-2): `TTL Y=9 55` selects PWM on OUT0 and sets the duty to 55."""
    ms.run([(b"TTL Y=9 55\r", ACK), (b"TTL Y?\r", b":A Y=9\r\n"), (b"LED X?\r", b"X=55 :A\r\n")])
    assert ms.get("ttl_out0_pwm") == 55


def test_tv_017_trailing_duty_ignored_by_knob(connect: Callable[..., Host]) -> None:
    """TV-17 (MS-LED-3): with `ttl_pwm_trailing_value: ignore` the bare number is only accepted."""
    host = connect(overrides={"knobs": {"ttl_pwm_trailing_value": "ignore"}})
    host.run([(b"TTL Y=9 55\r", ACK), (b"LED X?\r", b"X=0 :A\r\n")])


@pytest.mark.control
def test_tv_184_duty_reaches_out0_only_in_pwm_mode(ms: Host) -> None:
    """TV-184 (MS-LED-1, MS-LED-2): the duty is stored at once but drives OUT0 only in mode 9;
    0…100 only."""
    ms.run([(b"LED X=10\r", ACK), (b"LED X? Y?\r", b"X=10 Y=0 :A\r\n")])
    assert ms.get("ttl_out0_pwm") == 0
    ms.ask(b"TTL Y=9\r", ACK)
    assert ms.get("ttl_out0_pwm") == 10
    ms.ask(b"LED X=101\r", b":N-4\r\n")


def test_extra_channels_take_an_intensity(ms: Host) -> None:
    """MS-LED-1, MS-LED-2: Micro-Manager's ASIStage LED device opens channel 1 with `LED Y=<intensity>`
    and closes it with `LED Y=0`; 0…100 on every channel, the value reads back, 101 is `:N-4`."""
    ms.run(
        [
            (b"LED Y=20\r", ACK),
            (b"LED Y? Z?\r", b"Y=20 Z=0 :A\r\n"),
            (b"LED Z=100 F=1\r", ACK),
            (b"LED F=101\r", b":N-4\r\n"),
            (b"LED Y=0\r", ACK),
            (b"LED Y? Z? F?\r", b"Y=0 Z=100 F=1 :A\r\n"),
        ]
    )
