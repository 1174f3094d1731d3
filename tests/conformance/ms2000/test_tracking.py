"""TRACKING (PhotoTrack, §9.12) on profile `ms2000-track`: TV-205…TV-207."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tests.conformance.ms2000.conftest import ACK, Host


@pytest.fixture
def track(connect: Callable[..., Host]) -> Host:
    return connect("ms2000-track")


@pytest.mark.control
def test_tv_205_toggle_and_pause(track: Host) -> None:
    """TV-205 (MS-TRACK-1): bare `LK` starts tracking; a sum (400) below `LK Z` pauses it."""
    track.input("pmt", q1=100, q2=100, q3=100, q4=100)
    track.run(
        [
            (b"LK X?\r", b":A I\r\n"),
            (b"LK\r", ACK),
            (b"LK X?\r", b":A T\r\n"),
            (b"LK Z=1000\r", ACK),
            (b"LK X?\r", b":A P\r\n"),
        ]
    )


@pytest.mark.smoke
def test_tv_206_parameters_and_report(track: Host) -> None:
    """TV-206 (MS-TRACK-2): `LR` queries in F6; bare `LR Z` is a bare multi-line report."""
    track.ask(b"LR X? Y? F?\r", b":A X=1.000000 Y=0.500000 F=0.010000\r\n")
    report = track.reply(b"LR Z\r")
    assert not report.startswith(b":A") and len(report[:-2].split(b"\r")) > 1


@pytest.mark.control
def test_tv_207_stage_follows_and_reports_the_sum(track: Host) -> None:
    """TV-207 (MS-TRACK-3): with the object towards +X the X target grows within 100 ms of
    tracking; IN0 mode 5 report lines end with the sum 600."""
    track.ask(b"LK\r", ACK)
    track.advance(0.1, ("pmt", {"q1": 200, "q2": 100, "q3": 100, "q4": 200}))
    assert track.axis("X")["target_user_mm"] > 0
    track.ask(b"TTL X=5\r", ACK)
    track.input("ttl_in0", pulse_ms=5)
    for _ in range(2):
        line = track.port.read_until(b"\r\n")
        assert line.endswith(b"\r\n") and line.split()[-1] == b"600"
    track.ask(b"TTL X=0\r", ACK)
    track.drain()
