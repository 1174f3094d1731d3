"""RING BUFFER module (§9.2): TV-139…TV-145."""

from __future__ import annotations

import pytest

from tests.conformance.ms2000.conftest import ACK, IDLE, Host, Step

TWO_POSITIONS: list[Step] = [
    (b"RM X=0\r", ACK),
    (b"LD X=1000 Y=2000\r", ACK),
    (b"LD X=3000 Y=4000\r", ACK),
    (b"RM X?\r", b":A X=2\r\n"),
    (b"LD X? Y?\r", b":A X=1000 Y=2000\r\n"),
]
PLAY_IN_TURN: list[Step] = [
    (b"RM\r", ACK),
    IDLE,
    (b"W X Y\r", b":A 1000 2000\r\n"),
    (b"LD X? Y?\r", b":A X=3000 Y=4000\r\n"),
    (b"RM\r", ACK),
    IDLE,
    (b"W X Y\r", b":A 3000 4000\r\n"),
    (b"RM\r", ACK),
    IDLE,
    (b"W X Y\r", b":A 1000 2000\r\n"),
]


def test_tv_139_load_and_read(ms: Host) -> None:
    """TV-139 (MS-RB-2, MS-RB-3, MS-RB-4): LOAD fills slots in turn; `LD X? Y?` reads the slot at
    the pointer."""
    ms.run(TWO_POSITIONS)


def test_tv_140_bare_rm_steps_through_the_buffer(ms: Host) -> None:
    """TV-140 (MS-RB-5), after TV-139: each bare `RM` moves to the slot at the pointer and advances
    it, wrapping after the last."""
    ms.run([*TWO_POSITIONS, *PLAY_IN_TURN])


def test_tv_141_pointer_mode_and_autoplay(ms: Host) -> None:
    """TV-141 (MS-RB-4, MS-RB-5), after TV-140: the pointer and mode are range-checked; in mode 3 a
    trigger starts repeating autoplay (bit 7 of `RM F?` set) and the next one stops it."""
    ms.run([*TWO_POSITIONS, *PLAY_IN_TURN])
    ms.run(
        [
            (b"RM Z=5\r", b":N-4\r\n"),
            (b"RM F=0\r", b":N-4\r\n"),
            (b"RM Y?\r", b":A Y=3\r\n"),
            (b"RM F=3\r", ACK),
            (b"RT Z=300\r", ACK),
            (b"RM\r", ACK),
            (b"RM F?\r", b":A F=131\r\n"),
            (b"RM\r", ACK),
            (b"RM F?\r", b":A F=3\r\n"),
        ]
    )


@pytest.mark.smoke
def test_tv_142_buffer_full(ms: Host) -> None:
    """TV-142 (MS-RB-1, MS-RB-2): 50 slots; the 51st LOAD is out of range."""
    ms.run(
        [
            (b"RM X=0\r", ACK),
            *[(b"LD X=1\r", ACK)] * 50,
            (b"LD X=1\r", b":N-4\r\n"),
            (b"RM X?\r", b":A X=50\r\n"),
        ]
    )


def test_tv_143_load_current_position(ms: Host) -> None:
    """TV-143 (MS-RB-2): `LD X+ Y+` stores where the axes are."""
    ms.run(
        [
            (b"M X=1000\r", ACK),
            IDLE,
            (b"RM X=0\r", ACK),
            (b"LD X+ Y+\r", ACK),
            (b"LD X? Y?\r", b":A X=1000 Y=0\r\n"),
        ]
    )


@pytest.mark.control
def test_tv_144_buttons_store_and_clear(ms: Host) -> None:
    """TV-144 (MS-RB-6): the joystick button held 2 s stores the position; home held 1.5 s clears."""
    ms.ask(b"RM X=0\r", ACK)
    ms.advance(2.0, ("button", {"name": "joystick", "ms": 2000}))
    ms.ask(b"RM X?\r", b":A X=1\r\n")
    ms.advance(1.5, ("button", {"name": "home", "ms": 1500}))
    ms.ask(b"RM X?\r", b":A X=0\r\n")


@pytest.mark.control
def test_tv_145_z_sequence_on_in0_pulses(ms: Host) -> None:
    """TV-145 (MS-RB-7, MS-RB-5, MS-90): Micro-Manager's Z sequence: Z only (`RM Y=4`), IN0 mode 1,
    each pulse moves to the next slot."""
    ms.run(
        [
            (b"RM X=0\r", ACK),
            (b"LD Z=100\r", ACK),
            (b"LD Z=200\r", ACK),
            (b"RM Y=4 Z=0\r", ACK),
            (b"TTL X=1\r", ACK),
        ]
    )
    for reply in (b":A 100\r\n", b":A 200\r\n", b":A 100\r\n"):
        ms.input("ttl_in0", pulse_ms=1)
        ms.run([IDLE, (b"W Z\r", reply)])
    ms.ask(b"TTL X=0\r", ACK)
