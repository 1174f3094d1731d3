"""TV-38 ... TV-45: reset, status FLAGS, programs and the display (MP-55 ... MP-75)."""

from __future__ import annotations

from typing import Any

import pytest

from protocols.mp285 import Download, Vector
from tests.conformance.mp285.wire import (
    CHAR,
    CR,
    GET_POSITION,
    LONG_X,
    RESET,
    TEN_UM,
    X_250,
    ZEROS,
    OpenTarget,
    assert_halted,
    begin,
    connect,
    expect_at,
    frozen,
    hx,
    position,
    show,
    wait_state,
)

#: TV-41: program 1 = move vector (+250, 0, -250), pause
PROGRAM_1 = hx("64 01 02 D0 07 00 00 FA 00 00 00 00 00 00 00 06 FF FF FF") + bytes(16) + CR
UPLOAD_1 = hx("02 D0 07 00 00 FA 00 00 00 00 00 00 00 06 FF FF FF") + bytes(16) + CR
PAUSED_AT = hx("FA 00 00 00 00 00 00 00 06 FF FF FF 0D")


def test_tv_038_reset_answers_nothing_and_restores_defaults(open_target: OpenTarget) -> None:
    """TV-38 (MP-15, MP-55, MP-57): after `V` 777 µm/s high and `b`, `72 0D` answers nothing for a
    second (on a daemon device time runs 5×); then the power-on `V` word is back (XSPEED
    `C8 00`, FLAGS_2 `78`) and moves are absolute again (the same `m` twice stays at X = 250)."""
    host = connect(open_target, scale=5)
    host.exchange(hx("56 09 83 0D"), CR)
    host.exchange(hx("62 0D"), CR)
    host.send(RESET)
    host.quiet(1.0)
    host.exchange(GET_POSITION, ZEROS + CR)
    status = host.status()
    assert (show(status[28:30]), status[15]) == ("C8 00", 0x78)
    host.exchange(X_250, CR, within=0.2)
    host.exchange(X_250, CR, within=0.15)
    host.exchange(GET_POSITION, position(250))


@pytest.mark.timing
@pytest.mark.parametrize(
    ("overrides", "first", "scale"),
    [
        pytest.param(None, b"", 0.1, marks=pytest.mark.smoke),
        ({"knobs": {"reset_emits_nul": True}}, b"\x00", 1.0),
    ],
    ids=["default", "nul"],
)
def test_tv_038_reset_deaf_time(
    open_target: OpenTarget, overrides: dict[str, Any] | None, first: bytes, scale: float
) -> None:
    """TV-38 (MP-56, MP-58): a `63 0D` arriving 0.10 s after the reset is lost without a reply, one
    arriving at 0.30 s is answered (deaf for 0.2 s; both 0.1 s from its end, far beyond the timing
    slack; for the smoke sample device time runs at a tenth on a daemon, so that is 1 s of wall
    time, beyond any stall beside `make test`'s workers). `reset_emits_nul`: one `00` as the deaf
    time starts, one character time after the reset (at full speed: the serial test cable paces
    characters on the wall clock)."""
    host = connect(open_target, overrides=overrides, scale=scale)
    done = host.send(RESET)
    if first:
        host.expect_at(first, host.after(done, CHAR))
    host.quiet_until(host.after(done, 0.10 - 2 * CHAR))
    host.send(GET_POSITION)
    host.quiet_until(host.after(done, 0.30 - 2 * CHAR))
    host.exchange(GET_POSITION, ZEROS + CR)
    host.quiet(0.05)


@pytest.mark.control
def test_tv_039_reset_during_a_move(open_target: OpenTarget) -> None:
    """TV-39 (MP-57): `72 0D` at 1.000 s into the TV-31 move halts it at X = 5000 (`0D` at 1.150 s),
    then takes effect: deaf until 1.350 s, and no byte but the move's `0D`."""
    target, host, clock = frozen(open_target)
    begin(target, host, clock, LONG_X)
    clock.to(1.0)
    host.send(RESET)
    wait_state(target, "STOPPING")
    expect_at(host, clock, 1.15, CR)
    assert target.get("state") == "DEAF"
    clock.to(1.349)
    assert target.get("state") == "DEAF"
    clock.past(1.35)
    assert target.get("state") == "IDLE"
    host.exchange(GET_POSITION, position(5000))


def test_tv_039_reset_during_a_move_on_the_host_clock(open_target: OpenTarget) -> None:
    """TV-39 (MP-57, MP-56): `72 0D` reaching the device 1.000 s into the TV-31 move: the move's
    `0D` at 1.150 s; a `63 0D` at 1.25 s is lost (deaf until 1.350 s), one at 1.45 s answered with
    where the reset halted the axes (both 0.1 s from the end of the deaf time, far beyond the timing
    slack)."""
    host = connect(open_target)
    moved = host.send(LONG_X)
    host.quiet_until(moved + 1.0 - CHAR)
    host.send(RESET)  # its first byte halts the move
    host.expect_at(CR, moved + 1.15 + CHAR)
    host.quiet_until(moved + 1.25 - 2 * CHAR)
    host.send(GET_POSITION)
    host.quiet_until(moved + 1.45 - 2 * CHAR)
    assert_halted(host, host.position(), 1.0)
    host.quiet(0.05)


@pytest.mark.parametrize(
    ("overrides", "after_a", "after_b"),
    [
        (None, 0x40, 0x40),
        ({"knobs": {"flags_bit5_tracks_move_mode": True}}, 0x40, 0x60),
        ({"knobs": {"flags_bit5_tracks_move_mode": True, "flags_bit5_relative_is_set": False}}, 0x60, 0x40),
    ],
    ids=["stored", "tracks", "tracks-reversed"],
)
def test_tv_040_flags_bit_5(
    open_target: OpenTarget, overrides: dict[str, Any] | None, after_a: int, after_b: int
) -> None:
    """TV-40 (MP-64, MP-34): FLAGS bit 5 is the stored value and ignores `a`/`b`; with
    `flags_bit5_tracks_move_mode` it follows them (set = relative, or reversed)."""
    host = connect(open_target, overrides=overrides)
    host.exchange(hx("61 0D"), CR)
    assert host.status()[0] == after_a
    host.exchange(hx("62 0D"), CR)
    assert host.status()[0] == after_b


@pytest.mark.parametrize(
    ("overrides", "second"),
    [
        (None, hx("F4 01 00 00 00 00 00 00 0C FE FF FF 0D")),
        ({"knobs": {"program_vectors": "follow_mode"}}, PAUSED_AT),
    ],
    ids=["relative", "follow_mode"],
)
def test_tv_041_program_round_trip(
    open_target: OpenTarget, overrides: dict[str, Any] | None, second: bytes
) -> None:
    """TV-41 (MP-66, MP-16, MP-17, MP-72, MP-68, MP-70, MP-69): `d` stores a 16-byte move vector
    (`D0 07 00 00`) and a pause; `u` gives them back byte for byte; `k` answers at the pause; `e`
    answers at once (the pause was last), twice; `k` again moves by the vector once more, or, with
    `program_vectors: follow_mode`, to it (already there)."""
    assert Download(1, (Vector.move(250, 0, -250), Vector.pause())).encode() == PROGRAM_1
    host = connect(open_target, overrides=overrides)
    host.exchange(PROGRAM_1, CR)
    host.exchange(hx("75 01 0D"), UPLOAD_1)
    host.exchange(hx("6B 01 0D"), CR, within=0.2)
    host.exchange(GET_POSITION, PAUSED_AT)
    host.exchange(hx("65 0D"), CR)
    host.exchange(hx("65 0D"), CR)
    host.exchange(hx("6B 01 0D"), CR, within=0.2)
    host.exchange(GET_POSITION, second)


@pytest.mark.timing
@pytest.mark.parametrize(
    ("overrides", "again"),
    [(None, 0.200), ({"knobs": {"program_vectors": "follow_mode"}}, 0.150)],
    ids=["relative", "follow_mode"],
)
def test_tv_041_program_reply_times(
    open_target: OpenTarget, overrides: dict[str, Any] | None, again: float
) -> None:
    """TV-41 (MP-68, MP-70): `k` answers at 0.200 s (the vector's move and settle), `e` at once, the
    second `k` at 0.200 s, or 0.150 s with `follow_mode` (a move to where the axes are)."""
    host = connect(open_target, overrides=overrides)
    host.exchange(PROGRAM_1, CR)
    done = host.send(hx("6B 01 0D"))
    host.expect_at(CR, done + 0.200 + CHAR, within=0.2)
    done = host.send(hx("65 0D"))
    host.expect_at(CR, done + CHAR)
    done = host.send(hx("6B 01 0D"))
    host.expect_at(CR, done + again + CHAR, within=0.2)


@pytest.mark.parametrize(
    "frame", [pytest.param("6B 00 0D", marks=pytest.mark.smoke), "6B 0B 0D", "75 0B 0D", "64 01 00 0D"]
)
def test_tv_042_bad_program_frames(open_target: OpenTarget, frame: str) -> None:
    """TV-42 (MP-67, MP-72): `k`/`u` of program 0 or 11, and a `d` of 0 vectors: `34 0D` as the CR
    arrives, and nothing is stored: program 1 keeps what it held."""
    host = connect(open_target)
    host.exchange(PROGRAM_1, CR)
    done = host.send(hx(frame))
    host.expect_at(hx("34 0D"), done + 2 * CHAR)
    host.quiet(0.05)
    host.exchange(hx("75 01 0D"), UPLOAD_1)


def test_tv_042_download_checked_after_the_frame(open_target: OpenTarget) -> None:
    """TV-42 (MP-67): `d` of program 11 is read whole (20 bytes) before `34 0D`; a vector whose
    descriptor is `00 00 07 D0` (not a move vector) is refused and nothing is stored: program 1
    keeps what it held."""
    host = connect(open_target)
    host.exchange(PROGRAM_1, CR)
    frame = hx("64 0B 01 D0 07 00 00") + bytes(12) + CR
    host.send(frame[:-1])
    host.quiet(0.05)
    host.exchange(frame[-1:], hx("34 0D"))
    host.exchange(hx("64 01 01 00 00 07 D0") + bytes(12) + CR, hx("34 0D"))
    host.exchange(hx("75 01 0D"), UPLOAD_1)


def test_tv_042_empty_slot(open_target: OpenTarget) -> None:
    """TV-42 (MP-72): a never-downloaded program uploads as `00 0D` and executes as `0D`, nothing
    moving."""
    host = connect(open_target)
    host.exchange(hx("75 02 0D"), hx("00 0D"))
    host.exchange(hx("6B 02 0D"), CR)
    host.exchange(GET_POSITION, ZEROS + CR)


@pytest.mark.control
def test_tv_043_ctrl_c_abandons_a_running_program(open_target: OpenTarget) -> None:
    """TV-43 (MP-54): program 1's first vector is (+25,000, 0, 0); ^C at 1.000 s: `3D`, `0D` at
    1.150 s; the program is abandoned, so `e` answers at once. (A pause and a second move vector
    follow, so a program wrongly left paused would show: `e` would move X.)"""
    target, host, clock = frozen(open_target)
    program = (Vector.move(25_000, 0, 0), Vector.pause(), Vector.move(250, 0, 0))
    host.exchange(Download(1, program).encode(), CR)
    begin(target, host, clock, hx("6B 01 0D"))
    clock.to(1.0)
    host.exchange(hx("03"), hx("3D"))
    expect_at(host, clock, 1.15, CR)
    assert target.get("program") is None
    host.exchange(hx("65 0D"), CR)
    host.exchange(GET_POSITION, position(5000))


def test_tv_043_ctrl_c_abandons_a_paused_program(open_target: OpenTarget) -> None:
    """TV-43 (MP-71): while TV-41's program is paused the controller is idle: `c` is answered, ^C
    abandons the program and answers `0D`, `e` then answers at once without moving (a move vector
    after the pause would otherwise run)."""
    host = connect(open_target)
    program = (Vector.move(250, 0, -250), Vector.pause(), Vector.move(250, 0, -250))
    host.exchange(Download(1, program).encode(), CR)
    host.exchange(hx("6B 01 0D"), CR, within=0.2)
    host.exchange(GET_POSITION, PAUSED_AT)
    host.exchange(hx("03"), CR)
    host.exchange(hx("65 0D"), CR)
    host.exchange(GET_POSITION, PAUSED_AT)


def test_tv_044_programs_survive_reset(open_target: OpenTarget) -> None:
    """TV-44 (MP-73): after `d`, `72 0D` and 0.3 s, `u` gives the same 34 bytes."""
    host = connect(open_target)
    host.exchange(PROGRAM_1, CR)
    host.send(RESET)
    host.quiet(0.3)
    host.exchange(hx("75 01 0D"), UPLOAD_1)


@pytest.mark.control
@pytest.mark.parametrize(
    ("retention", "after_reset", "after_power_cycle"),
    [
        ("power_cycle", UPLOAD_1, hx("00 0D")),
        ("reset", hx("00 0D"), hx("00 0D")),
        ("always", UPLOAD_1, UPLOAD_1),
    ],
)
def test_tv_044_program_retention(
    open_target: OpenTarget, retention: str, after_reset: bytes, after_power_cycle: bytes
) -> None:
    """TV-44 (MP-73, MP-76): programs survive `r` and are lost at a power cycle (1.1 s later `u`
    gives `00 0D`); `program_retention: reset` loses them at `r` too, `always` never."""
    target, host, clock = frozen(open_target, overrides={"knobs": {"program_retention": retention}})
    host.exchange(PROGRAM_1, CR)
    begin(target, host, clock, RESET, "DEAF")
    clock.past(0.3)
    host.exchange(hx("75 01 0D"), after_reset)
    target.input("power_cycle")
    assert target.get("state") == "POWERING_ON"
    clock.past(0.3 + 1.1)
    host.exchange(hx("75 01 0D"), after_power_cycle)


@pytest.mark.control
def test_tv_045_display_refresh(open_target: OpenTarget) -> None:
    """TV-45 (MP-74, MP-75): after the TV-18 move the display still shows the old coordinates; `n`
    refreshes them; an error reply shows on line 2."""
    host = connect(open_target)
    target = host.target
    host.exchange(TEN_UM, CR, within=0.2)
    assert target.get("display")[0] == "X:+0.00 Y:+0.00 Z:+0.00"
    host.exchange(hx("6E 0D"), CR)
    assert target.get("display") == ["X:+10.00 Y:+10.00 Z:+10.00", ""]
    host.exchange(hx("78 0D"), hx("34 0D"))
    assert target.get("display")[1] == "ERR 4"
