"""ARRAY MODULE (§9.1): TV-129…TV-138.

The vectors run on profile `ms2000-seq` (SEQUENCER without a program leaves `@` and the array to
ARRAY); TV-137 runs on `ms2000-all-modules`, whose LCD shows ARRAY's own segment.
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tests.conformance.ms2000.conftest import ACK, IDLE, Host

TWO_BY_TWO = [(b"AR X=2 Y=2 Z=1 F=1\r", ACK), (b"RT Z=50\r", ACK)]
#: one device-time step while watching the state machine on a paused clock
STEP_S = 0.005


@pytest.fixture
def seq(connect: Callable[..., Host]) -> Host:
    return connect("ms2000-seq")


def arrivals(host: Host, count: int, timeout: float = 2.0) -> list[tuple[int, int]]:
    """The next `count` `array_arrival` events (fewer if none comes for `timeout` s)."""
    cells: list[tuple[int, int]] = []
    for event in host.target.ctl().events(timeout=timeout):
        if event["ev"] == "array_arrival":
            cells.append((event["i"], event["j"]))
            if len(cells) == count:
                break
    return cells


@pytest.mark.smoke
def test_tv_129_grid_defaults_and_range(seq: Host) -> None:
    """TV-129 (MS-ARRAY-1): the 96-well plate defaults; zero columns is out of range."""
    seq.run(
        [
            (b"AR X? Y? Z? F? T?\r", b":A X=12 Y=8 Z=9.000000 F=-9.000000 T=0.000000\r\n"),
            (b"AR X=0\r", b":N-4\r\n"),
            (b"AR Y=1001\r", b":N-4\r\n"),
            (b"AR X=2.5\r", b":N-4\r\n"),
        ]
    )


def test_tv_130_aij_moves_to_a_cell(seq: Host) -> None:
    """TV-130 (MS-ARRAY-4, MS-ARRAY-3): cell (2,3) of the default grid; column 13 does not exist."""
    seq.run(
        [
            (b"AIJ X=2 Y=3\r", ACK),
            (b"/\r", b"B\r\n"),
            IDLE,
            (b"W X Y\r", b":A 90000 -180000\r\n"),
            (b"AIJ X? Y?\r", b":A X=2 Y=3\r\n"),
            (b"AIJ X=13 Y=1\r", b":N-4\r\n"),
        ]
    )


def test_tv_131_ahome(seq: Host) -> None:
    """TV-131 (MS-ARRAY-2): `AH X= Y=` sets cell (1,1) in mm; bare `AH` takes the current position."""
    seq.run(
        [
            (b"AH X=1 Y=2\r", ACK),
            (b"AH X?\r", b":A X=1.000000\r\n"),
            (b"AIJ X=1 Y=1\r", ACK),
            IDLE,
            (b"W X Y\r", b":A 10000 20000\r\n"),
            (b"M X=5000 Y=5000\r", ACK),
            IDLE,
            (b"AH\r", ACK),
            (b"AH X? Y?\r", b":A X=0.500000 Y=0.500000\r\n"),
        ]
    )


def test_tv_132_tilt(seq: Host) -> None:
    """TV-132 (MS-ARRAY-3): with a 90° tilt the columns run along +Y."""
    seq.run([(b"AR T=90\r", ACK), (b"AIJ X=2 Y=1\r", ACK), IDLE, (b"W X Y\r", b":A 0 90000\r\n")])


@pytest.mark.control
def test_tv_133_self_scan_serpentine_through_complete(seq: Host) -> None:
    """TV-133 (MS-ARRAY-5, MS-ARRAY-7): serpentine by default; bare `AR` visits the 2×2 array in
    that order, moving (M) to each cell and dwelling (D) there, then C and idle; watched step by step
    on a paused clock."""
    seq.run([*TWO_BY_TWO, (b"SN F?\r", b":A F=1\r\n"), (b"M X=5000\r", ACK), IDLE])
    ctl = seq.target.ctl()
    ctl.subscribe("dut")
    seq.ask(b"AR\r", ACK)
    seen = ""
    ctl.pause()
    try:
        for _ in range(round(10 / STEP_S)):
            ctl.step(STEP_S)
            state = seq.get("array")["state"]
            if not seen or state != seen[-1]:
                seen += state
            if state == "I":
                break
    finally:
        ctl.resume()
    assert arrivals(seq, 4) == [(1, 1), (2, 1), (2, 2), (1, 2)]
    assert seen == "MDMDMDMCI"


@pytest.mark.control
def test_tv_134_raster_order(seq: Host) -> None:
    """TV-134 (MS-ARRAY-5, MS-SCAN-1): with `SN F=0` every row runs the same way."""
    seq.run([*TWO_BY_TWO, (b"SN F=0\r", ACK)])
    seq.target.ctl().subscribe("dut")
    seq.ask(b"AR\r", ACK)
    assert arrivals(seq, 4) == [(1, 1), (2, 1), (1, 2), (2, 2)]


@pytest.mark.control
def test_tv_135_commanded_stepping(seq: Host) -> None:
    """TV-135 (MS-ARRAY-6): `RM X=1` goes to (1,1) in IN0 mode 7; each pulse to the next cell; a
    fourth pulse after the last cell moves nothing."""
    seq.run(TWO_BY_TWO)
    seq.target.ctl().subscribe("dut")
    seq.run([(b"TTL X=7\r", ACK), (b"RM X=1\r", ACK)])
    assert arrivals(seq, 1) == [(1, 1)]
    for cell in ((2, 1), (2, 2), (1, 2)):
        seq.idle()
        seq.input("ttl_in0", pulse_ms=1)
        assert arrivals(seq, 1) == [cell]
    seq.idle()
    seq.input("ttl_in0", pulse_ms=1)
    seq.ask(b"/\r", b"N\r\n")
    assert arrivals(seq, 1, timeout=0.5) == []


@pytest.mark.control
@pytest.mark.parametrize(("knob", "expected"), [(True, [(1, 1)]), (False, [])], ids=["knob_on", "knob_off"])
def test_tv_136_rm_x0_starts_only_with_the_knob(
    connect: Callable[..., Host], knob: bool, expected: list[tuple[int, int]]
) -> None:
    """TV-136 (MS-ARRAY-6): in IN0 mode 7, `RM X=0` also moves to (1,1) with knob
    `array_start_on_rm_x0: true`; with it false it only clears the ring buffer."""
    host = connect("ms2000-seq", {"knobs": {"array_start_on_rm_x0": knob}})
    host.run([*TWO_BY_TWO, (b"M X=5000\r", ACK), IDLE, (b"TTL X=7\r", ACK)])
    host.target.ctl().subscribe("dut")
    host.ask(b"RM X=0\r", ACK)
    assert arrivals(host, 1, timeout=1.0) == expected


@pytest.mark.control
def test_tv_137_array_observable_and_lcd(connect: Callable[..., Host]) -> None:
    """TV-137 (MS-ARRAY-7): after `AIJ X=3 Y=2` the state is A at (3,2), no scan running; with 8 rows
    the LCD shows the row as a letter, with 5 as a number."""
    host = connect("ms2000-all-modules")
    host.run([(b"AIJ X=3 Y=2\r", ACK), IDLE])
    assert host.get("array") == {"state": "A", "i": 3, "j": 2, "running": None}
    assert "A 3,B" in host.get("lcd")[1]
    host.ask(b"AR Y=5\r", ACK)
    assert "A 3,2" in host.get("lcd")[1]


@pytest.mark.control
def test_tv_138_out0_pulse_per_arrival(seq: Host) -> None:
    """TV-138 (MS-ARRAY-8): in OUT0 mode 2 a self-scan of the 2×2 array pulses OUT0 four times."""
    seq.run([*TWO_BY_TWO, (b"TTL Y=2\r", ACK)])
    ctl = seq.target.ctl()
    ctl.subscribe("dut")
    seq.ask(b"AR\r", ACK)
    pulses, cells = 0, 0
    for event in ctl.events(timeout=2.0):
        if event["ev"] == "ttl_out0" and event["level"] == 1:
            pulses += 1
        elif event["ev"] == "array_arrival":
            cells += 1
        elif event["ev"] == "ttl_out0" and cells == 4:
            break  # the last pulse has ended
    assert (cells, pulses) == (4, 4)
