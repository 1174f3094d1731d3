"""The small firmware modules: NO CHANGE SETTINGS (§7), PEDALS (§9.14), XY KNOBS (§9.15), SEARCH
INDEX / SEEK LIMITS (§9.16) and SOL_LK / U_SERVO_LK (§9.17): TV-92, TV-210…TV-214, TV-216, TV-217.

The vectors run on the test-only profile `ms2000-all-modules`.
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tests.conformance.ms2000.conftest import ACK, IDLE, Host


@pytest.fixture
def allmod(connect: Callable[..., Host]) -> Host:
    return connect("ms2000-all-modules")


@pytest.mark.smoke
def test_tv_092_write_protect_speed(allmod: Host) -> None:
    """TV-92 (MS-109): `VB T=1027` write-protects SPEED (its sets `:N-4`), `VB T=27` releases it."""
    allmod.run(
        [
            (b"VB T=1027\r", ACK),
            (b"S X=1\r", b":N-4\r\n"),
            (b"VB T=27\r", ACK),
            (b"S X=1\r", ACK),
            (b"S X?\r", b":A X=1.000000\r\n"),
        ]
    )


@pytest.mark.control
def test_tv_210_pedal_tap(allmod: Host) -> None:
    """TV-210 (MS-PEDAL-1, MS-PEDAL-2): the defaults; a 100 ms tap of the up pedal moves Z 1 µm."""
    allmod.ask(b"PEDAL X? Y? Z?\r", b":A X=0.001000 Y=1 Z=1\r\n")
    allmod.advance(1.0, ("pedal", {"which": "up", "ms": 100}))
    allmod.ask(b"W Z\r", b":A 10\r\n")


@pytest.mark.control
def test_tv_211_xy_knob_turn(allmod: Host) -> None:
    """TV-211 (MS-KNOB-1, MS-KNOB-2, MS-74): knob speeds read by name; 100 counts at the fast speed
    1 × 4³ move X by 640 µm."""
    allmod.ask(b"JS F? T?\r", b":A KNOB_SLOW=1.000000 KNOB_MULT=4\r\n")
    allmod.advance(1.0, ("xy_knob", {"x_counts": 100}))
    allmod.ask(b"W X\r", b":A 6400\r\n")


def test_tv_212_search_index(allmod: Host) -> None:
    """TV-212 (MS-SI-1): a search replies when over and sets the position; repeating it unmoved
    is `:N-5`."""
    allmod.run(
        [
            (b"SI X=0\r", ACK),
            (b"SI X=0\r", b":N-5\r\n"),
            (b"SI Y=20000\r", ACK),
            (b"W Y\r", b":A 20000\r\n"),
            (b"SI X? Y?\r", b":A X=0 Y=20000\r\n"),
        ]
    )


@pytest.mark.control
def test_tv_213_index_missing(allmod: Host) -> None:
    """TV-213 (MS-SI-1): with the index missing the search fails and logs 100 + axis index; found
    again, it succeeds."""
    allmod.input("index_missing", axis="Y")
    allmod.run([(b"SI Y=5\r", b":N-5\r\n"), (b"DU Y\r", b"101\r:A\r\n")])
    assert allmod.input("index_missing", axis="Y", missing=False) == []
    allmod.ask(b"SI Y=5\r", ACK)


@pytest.mark.control
def test_tv_214_seek_limits(allmod: Host) -> None:
    """TV-214 (MS-SI-2, MS-SI-3): a seek replies at once, is busy until it stops on the upper limit
    (status byte 74): it runs to the limit, backs off 3 mm and approaches again; it reads back its
    direction and takes only ±1."""
    ctl = allmod.target.ctl()
    ctl.subscribe("dut")
    allmod.run([(b"SI Z=1\r", ACK), (b"/\r", b"B\r\n")])
    with allmod.scaled(10):
        allmod.run([IDLE])
    allmod.run(
        [
            (b"RS Z\r", b":A 74\r\n"),
            (b"SI Z?\r", b":A Z=1\r\n"),
            (b"SI Z=2\r", b":N-4\r\n"),
            (b"W Z\r", b":A 100000\r\n"),
        ]
    )
    legs = [e["positions"]["Z"] for e in ctl.events(timeout=0.5) if e["ev"] == "move_complete"]
    assert legs == ["100000", "70000", "100000"]


@pytest.mark.smoke
@pytest.mark.control
def test_tv_216_solenoid_lock(allmod: Host) -> None:
    """TV-216 (MS-SECURE-1): bare SECURE `:N-3`; `X=1` unlocks; the query replies value first."""
    allmod.run(
        [
            (b"SECURE\r", b":N-3\r\n"),
            (b"SECURE X=1\r", ACK),
            (b"SECURE X?\r", b"X=1 :A\r\n"),
        ]
    )
    assert allmod.get("secure") == {"locked": False, "position": 1.0}


def test_tv_217_micro_servo_lock(connect: Callable[..., Host]) -> None:
    """TV-217 (MS-SECURE-1): the micro-servo insert takes only a lever position and has no query."""
    connect("ms2000-uservo").run(
        [
            (b"SECURE X=0.25\r", ACK),
            (b"SECURE Y=\r", b":N-2\r\n"),
            (b"SECURE X?\r", b":N-2\r\n"),
        ]
    )


@pytest.mark.control
def test_tv_217_lever_position(connect: Callable[..., Host]) -> None:
    """TV-217 (MS-SECURE-1): the lever position is the insert's state (any position but 0 is open)."""
    host = connect("ms2000-uservo")
    host.ask(b"SECURE X=0.25\r", ACK)
    assert host.get("secure") == {"locked": False, "position": 0.25}


def test_tv_215_kind_without_its_module(connect: Callable[..., Host]) -> None:
    """TV-215 (MS-SI-3, MS-118): with SEARCH INDEX but not SEEK LIMITS, `SI` of the rotary Z is
    unknown, of the linear X a search."""
    host = connect("ms2000-all-modules", {"modules": ["SEARCH INDEX"]})
    host.run([(b"SI Z=1\r", b":N-1\r\n"), (b"SI X=0\r", ACK)])
