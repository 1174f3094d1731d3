"""MULTIAXIS MOVES module (§9.13): TV-208, TV-209.

The vectors run on the test-only profile `ms2000-all-modules` (X and Y linear).
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tests.conformance.ms2000.conftest import ACK, Host

CIRCLE = [(b"MM X=1 Y=0.5 F=64\r", ACK)]


@pytest.fixture
def multi(connect: Callable[..., Host]) -> Host:
    return connect("ms2000-all-modules")


@pytest.mark.smoke
def test_tv_208_parameters_and_idle_state(multi: Host) -> None:
    """TV-208 (MS-MULTI-1, MS-MULTI-2): parameters read back (F as an integer); idle is R=73."""
    multi.run(
        [
            *CIRCLE,
            (b"MM X? Y? F?\r", b":A X=1.000000 Y=0.500000 F=64\r\n"),
            (b"MM R?\r", b":A R=73.000000\r\n"),
            (b"MM F=256\r", b":N-4\r\n"),
            (b"MM X=-1\r", b":N-4\r\n"),
        ]
    )


def test_tv_209_running_refuses_moves_and_stops(multi: Host) -> None:
    """TV-209 (MS-MULTI-2, MS-MULTI-1), parameters as TV-208: running (R=67, status `T`, busy), a move
    of one of its axes is refused, of another axis taken; `R=80` stops it along the path, idle again
    later; other codes are out of range (82, a restart, is for fast circles only)."""
    multi.run(
        [
            *CIRCLE,
            (b"MM\r", ACK),
            (b"MM R?\r", b":A R=67.000000\r\n"),
            (b"RS X+\r", b":A T\r\n"),
            (b"/\r", b"B\r\n"),
            (b"M X=0\r", b":N-5\r\n"),
            (b"R Y=10\r", b":N-5\r\n"),
            (b"M Z=10\r", ACK),
            (b"MM R=80\r", ACK),
            (b"MM R?\r", b":A R=80.000000\r\n"),
        ]
    )
    deadline = multi.monotonic() + 5.0
    while (state := multi.reply(b"MM R?\r")) != b":A R=73.000000\r\n":
        assert state == b":A R=80.000000\r\n", state
        assert multi.monotonic() < deadline, "the pattern did not stop"
        multi.poll_pause()
    multi.run([(b"MM R=65\r", b":N-4\r\n"), (b"MM R=82\r", b":N-4\r\n")])
