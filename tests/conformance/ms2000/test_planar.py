"""PLANAR CORRECTION module (§9.9): TV-187…TV-192.

The vectors run on profile `ms2000-seq` (X and Y on linear encoders at 100000 counts/mm).
"""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tests.conformance.ms2000.conftest import ACK, IDLE, Host, Step

#: TV-187: points (0, 0, 0), (10 mm, 0, 0), (0, 10 mm, 10 µm); the plane rises 1 µm per mm of Y
FIRST_PLANE: list[Step] = [
    (b"CCB Z=1\r", ACK),
    (b"M X=100000\r", ACK),
    IDLE,
    (b"CCB Z=2\r", ACK),
    (b"M X=0 Y=100000 Z=100\r", ACK),
    IDLE,
    (b"CCB Z=3\r", ACK),
    (b"CCB Z=4\r", ACK),
    (b"M Z=0\r", ACK),
    (b"M Y=50000\r", ACK),
    IDLE,
    (b"W Z\r", b":A 0\r\n"),
    (b"CCB Z=6\r", b":A 50\r\n"),
]


@pytest.fixture
def seq(connect: Callable[..., Host]) -> Host:
    return connect("ms2000-seq")


def test_tv_187_three_points_and_correction(seq: Host) -> None:
    """TV-187 (MS-PC-1, MS-PC-2): Z follows the plane while `W Z` stays in plane coordinates;
    `CCB Z=6` reads the physical position."""
    seq.run(FIRST_PLANE)


@pytest.mark.smoke
def test_tv_188_errors(seq: Host) -> None:
    """TV-188 (MS-PC-1): two points fit no plane; 8 is out of range; no item is missing parameters."""
    seq.run(
        [
            (b"CCB Z=7\r", ACK),
            (b"CCB Z=1\r", ACK),
            (b"CCB Z=2\r", ACK),
            (b"CCB Z=4\r", b":N-5\r\n"),
            (b"CCB Z=8\r", b":N-4\r\n"),
            (b"CCB\r", b":N-3\r\n"),
            (b"CCB X=1\r", b":N-2\r\n"),
        ]
    )


@pytest.mark.control
def test_tv_189_state_characters(seq: Host) -> None:
    """TV-189 (MS-PC-3): 1, 2, 3 while selecting, G with three points, Z enabled (first on the LCD's
    line 2, in SEQUENCER's segment), G disabled: no tilt yet."""
    assert seq.get("planar")["state"] == "1"
    moves = {1: b"M X=100000\r", 2: b"M X=0 Y=100000\r"}
    for n, after in ((1, "2"), (2, "3"), (3, "G")):
        seq.ask(f"CCB Z={n}\r".encode(), ACK)
        assert seq.get("planar")["state"] == after
        if n in moves:
            seq.run([(moves[n], ACK), IDLE])
    seq.ask(b"CCB Z=4\r", ACK)
    assert seq.get("planar")["state"] == "Z"
    assert seq.get("lcd")[1].startswith("Z I ")
    seq.ask(b"CCB Z=5\r", ACK)
    planar = seq.get("planar")
    assert {key: planar[key] for key in ("state", "a", "b", "enabled")} == {
        "state": "G",
        "a": 0.0,
        "b": 0.0,
        "enabled": False,
    }


@pytest.mark.control
def test_tv_190_buttons_select_and_disable(seq: Host) -> None:
    """TV-190 (MS-PC-4): the joystick button held 3 s selects each point and enables after the
    third; beside RING BUFFER home must be held 6 s, not 3, to disable; held 3 s, the joystick
    button enables again; home held 6 s twice clears the points."""
    assert seq.get("planar")["state"] == "1"
    for move in (b"M X=0 Y=0\r", b"M X=100000\r", b"M X=0 Y=100000\r"):
        seq.run([(move, ACK), IDLE])
        seq.advance(3.0, ("button", {"name": "joystick", "ms": 3000}))
    assert seq.get("planar")["state"] == "Z"
    seq.advance(3.0, ("button", {"name": "home", "ms": 3000}))
    assert seq.get("planar")["state"] == "Z"
    seq.advance(6.0, ("button", {"name": "home", "ms": 6000}))
    assert seq.get("planar")["state"] == "G"
    seq.advance(3.0, ("button", {"name": "joystick", "ms": 3000}))
    assert seq.get("planar")["state"] == "Z"
    for _ in range(2):
        seq.advance(6.0, ("button", {"name": "home", "ms": 6000}))
    assert seq.get("planar")["state"] == "1"


@pytest.mark.control
def test_tv_191_saved_plane_survives_power_cycle(seq: Host) -> None:
    """TV-191 (MS-PC-5): `SS Z` keeps the tilt and the enabled flag over a power cycle; Z stays where
    it is and `W Z` reads as before."""
    seq.run(FIRST_PLANE)
    before = seq.get("planar")
    physical = seq.axis("Z")["machine_counts"]
    seq.ask(b"SS Z\r", ACK)
    seq.input("power_cycle")
    after = seq.get("planar")
    assert after["enabled"] is True
    assert (after["a"], after["b"]) == (before["a"], before["b"])
    assert seq.axis("Z")["machine_counts"] == physical
    seq.ask(b"W Z\r", b":A 0\r\n")


def test_tv_192_zero_rereferences_the_plane(seq: Host) -> None:
    """TV-192 (MS-PC-2), after TV-187 (Y at 5 mm): ZERO makes the correction 0 here; 5 mm further
    in Y it is 5 µm again."""
    seq.run(FIRST_PLANE)
    seq.run(
        [
            (b"Z\r", ACK),
            (b"CCB Z=6\r", b":A 0\r\n"),
            (b"M Y=50000\r", ACK),
            IDLE,
            (b"CCB Z=6\r", b":A 50\r\n"),
        ]
    )


@pytest.mark.control
def test_tv_192_zero_leaves_z_in_place(seq: Host) -> None:
    """TV-192 (MS-PC-2): ZERO re-references the plane without moving Z."""
    seq.run(FIRST_PLANE)
    physical = seq.axis("Z")["machine_counts"]
    seq.ask(b"Z\r", ACK)
    assert seq.axis("Z")["machine_counts"] == physical
