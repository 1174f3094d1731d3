"""SCAN MODULE with ENC_INT (§9.3) on profile `ms2000-scan`: TV-146…TV-153."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tests.conformance.ms2000.conftest import ACK, IDLE, Host, Step

#: TV-149's scan area: 1 mm lines at divide 24 (1891 pixels), three lines 0.05 mm apart
AREA: list[Step] = [(b"NR X=0 Y=1 Z=24\r", ACK), (b"NV X=0 Y=0.1 Z=3\r", ACK)]


@pytest.fixture
def scan(connect: Callable[..., Host]) -> Host:
    return connect("ms2000-scan")


def test_tv_146_factory_roles(scan: Host) -> None:
    """TV-146 (MS-SCAN-1): X fast, Y slow, Z unused, raster."""
    scan.ask(b"SN X? Y? Z? F?\r", b":A X=1 Y=2 Z=0 F=0\r\n")


@pytest.mark.smoke
def test_tv_147_scanr(scan: Host) -> None:
    """TV-147 (MS-SCAN-2): pixels from start, stop and divide; a pixel count sets the stop."""
    scan.run(
        [
            (b"NR X=0.0 Y=1.0 Z=24\r", ACK),
            (b"NR F?\r", b":A F=1891\r\n"),
            (b"NR X=0 Z=24 F=100\r", ACK),
            (b"NR Y?\r", b":A Y=0.052868\r\n"),
            (b"NR Z=40000\r", b":N-4\r\n"),
            (b"NR Z=7\r", b":N-4\r\n"),
            (b"NR F=0\r", b":N-4\r\n"),
        ]
    )


def test_tv_148_scanv(scan: Host) -> None:
    """TV-148 (MS-SCAN-3): lines and the default overshoot factor."""
    scan.run(
        [
            (b"NV X=0 Y=0.1 Z=3\r", ACK),
            (b"NV Z? F?\r", b":A Z=3 F=1.000000\r\n"),
            (b"NV X? Y?\r", b":A X=0.000000 Y=0.100000\r\n"),
        ]
    )


@pytest.mark.control
def test_tv_149_raster_scan_with_pixel_clock(scan: Host) -> None:
    """TV-149 (MS-SCAN-4): busy throughout the scan (states a, b, c, g per line, watched every 5 ms
    of device time on a paused clock); one SYNC and 1891 pixels per line; the fast axis returns to
    its start, the slow one stays on the last line; nothing is logged."""
    scan.run([*AREA, (b"TTL X=1\r", ACK), (b"M Y=-500\r", ACK), IDLE])  # the first slow move takes time
    ctl = scan.target.ctl()
    ctl.subscribe("dut")
    scan.run([(b"SN\r", ACK), (b"/\r", b"B\r\n")])
    seen = ""
    ctl.pause()
    try:
        while not seen.endswith("I"):
            assert len(seen) < 20 and scan.get("busy"), f"not busy in scan state {seen[-1:]}"
            ctl.step(0.005)
            state = scan.get("scan")["state"]
            if not seen or state != seen[-1]:
                seen += state
    finally:
        ctl.resume()
    assert seen == "abcgacgacgI"
    scan.run([(b"/\r", b"N\r\n"), (b"W X Y\r", b":A 0 1000\r\n"), (b"DU Y\r", ACK)])
    events = [
        (e["ev"], e["line"], e.get("count")) for e in ctl.events(timeout=0.5) if e["ev"].startswith("scan_")
    ]
    assert events == [
        ("scan_sync", n, None) if k == 0 else ("scan_pixels", n, 1891) for n in (1, 2, 3) for k in (0, 1)
    ]


@pytest.mark.control
def test_tv_150_stopping_a_running_scan_logs_86(scan: Host) -> None:
    """TV-150 (MS-SCAN-6, MS-SCAN-4, MS-SCAN-7): the running scan is in a moving state; `SN` stops
    it, logging 86 only."""
    scan.run([*AREA, (b"TTL X=1\r", ACK), (b"SN\r", ACK)])
    assert scan.get("scan")["state"] in ("a", "b", "c", "g")
    scan.ask(b"SN\r", ACK)
    assert scan.get("scan")["state"] == "P"  # while the moving axis ramps down
    assert scan.get("lcd")[1].startswith("RB 0/0 P")
    scan.run([IDLE, (b"DU Y\r", b"86\r:A\r\n")])
    assert scan.get("scan")["state"] == "I"


def test_tv_151_fast_axis_off_the_encoder_jumper_logs_85(scan: Host) -> None:
    """TV-151 (MS-SCAN-6): Y fast while the jumpers wire X: every line's pixel count is wrong."""
    scan.run(
        [
            *AREA,
            (b"SN X=2 Y=1\r", ACK),
            (b"TTL X=1\r", ACK),
            (b"SN\r", ACK),
            IDLE,
            (b"DU Y\r", b"85\r85\r85\r:A\r\n"),
        ]
    )


@pytest.mark.control
def test_tv_151_no_pixels_counted(scan: Host) -> None:
    """TV-151 (MS-SCAN-6): the counter of the jumpered encoder sees no pulse on any line."""
    scan.run([*AREA, (b"SN X=2 Y=1\r", ACK), (b"TTL X=1\r", ACK)])
    ctl = scan.target.ctl()
    ctl.subscribe("dut")
    scan.run([(b"SN\r", ACK), IDLE])
    assert [e["count"] for e in ctl.events(timeout=0.5) if e["ev"] == "scan_pixels"] == [0, 0, 0]


@pytest.mark.control
def test_tv_152_at_button_starts_and_aborts(scan: Host) -> None:
    """TV-152 (MS-SCAN-5): `@` held 1.5 s starts a scan when released (not before); a 200 ms press
    aborts it: state P while the moving axis ramps down."""
    scan.run(AREA)
    scan.advance(1.4, ("button", {"name": "at", "ms": 1500}))
    assert scan.get("scan")["state"] == "I"
    scan.advance(0.2)
    assert scan.get("scan")["state"] != "I"
    scan.advance(0.25, ("button", {"name": "at", "ms": 200}))
    assert scan.get("scan")["state"] == "P"
    scan.run([IDLE, (b"DU Y\r", b"86\r:A\r\n")])


def test_tv_153_start_needs_a_fast_axis(scan: Host) -> None:
    """TV-153 (MS-SCAN-1): with no fast axis (or two) bare `SN` fails."""
    scan.run([(b"SN X=0 Y=0\r", ACK), (b"SN\r", b":N-5\r\n"), (b"SN X=1 Y=1\r", ACK), (b"SN\r", b":N-5\r\n")])
