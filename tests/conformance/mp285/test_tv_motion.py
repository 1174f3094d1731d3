"""TV-18 ... TV-29: moves, modes, origin, travel limits and the `V` word (MP-28 ... MP-47)."""

from __future__ import annotations

from typing import Any

import pytest

from tests.conformance.mp285.wire import (
    CHAR,
    CR,
    GET_POSITION,
    TEN_UM,
    X_250,
    ZEROS,
    Host,
    OpenTarget,
    begin,
    connect,
    expect_at,
    frozen,
    hx,
    position,
    show,
)

#: TV-19: (-250, 0, 0)
MINUS_250 = hx("6D 06 FF FF FF 00 00 00 00 00 00 00 00 0D")
#: TV-21: X = 400,000, beyond the +312,500 travel limit of a centred origin
FAR_X = hx("6D 80 1A 06 00 00 00 00 00 00 00 00 00 0D")


def test_tv_018_ten_um_per_axis(open_target: OpenTarget) -> None:
    """TV-18 (MP-43, MP-44, MP-47): +10 µm per axis answers `0D`; the axes are at (250, 250, 250)."""
    host = connect(open_target)
    host.exchange(TEN_UM, CR, within=0.2)
    host.exchange(GET_POSITION, position(250, 250, 250))


@pytest.mark.timing
@pytest.mark.parametrize(
    ("overrides", "seconds"),
    [
        # 0.05 s of motion + 0.15 s settle; the round trip is about 0.216 s
        pytest.param(None, 0.200, marks=pytest.mark.smoke),
        ({"knobs": {"axis_motion": "sequential"}}, 0.300),  # 3 × 0.05 s + 0.15 s
        ({"knobs": {"accel_um_s2": 1000}}, 0.350),  # triangular: 2·√(10/1000) + 0.15 s
    ],
    ids=["simultaneous", "sequential", "accel"],
)
def test_tv_018_move_reply_time(
    open_target: OpenTarget, overrides: dict[str, Any] | None, seconds: float
) -> None:
    """TV-18 (MP-43, MP-44, MP-45): the move's `0D` at 0.200 s, 0.300 s (axes one after another)
    or 0.350 s (1000 µm/s² acceleration) after the frame."""
    host = connect(open_target, overrides=overrides)
    done = host.send(TEN_UM)
    host.expect_at(CR, done + seconds + CHAR, within=seconds)


def tv19(host: Host) -> None:
    """TV-19's exchange: (-250, 0, 0) relative, then the same values absolute (already there)."""
    host.exchange(hx("62 0D"), CR)
    host.exchange(MINUS_250, CR, within=0.2)
    host.exchange(GET_POSITION, hx("06 FF FF FF 00 00 00 00 00 00 00 00 0D"))
    host.exchange(hx("61 0D"), CR)
    host.exchange(MINUS_250, CR, within=0.15)
    host.exchange(GET_POSITION, hx("06 FF FF FF 00 00 00 00 00 00 00 00 0D"))


def test_tv_019_relative_and_absolute_modes(open_target: OpenTarget) -> None:
    """TV-19 (MP-33, MP-35): in relative mode `m` values are displacements, in absolute mode
    targets; `c` reports the same position in both."""
    tv19(connect(open_target))


@pytest.mark.timing
def test_tv_019_reply_times(open_target: OpenTarget) -> None:
    """TV-19 (MP-43, MP-44): the relative move answers at 0.200 s, the absolute one to where the
    axes already are after the settle time alone, 0.150 s."""
    host = connect(open_target)
    host.exchange(hx("62 0D"), CR)
    done = host.send(MINUS_250)
    host.expect_at(CR, done + 0.200 + CHAR, within=0.2)
    host.exchange(hx("61 0D"), CR)
    done = host.send(MINUS_250)
    host.expect_at(CR, done + 0.150 + CHAR, within=0.15)


def test_tv_020_set_origin(open_target: OpenTarget) -> None:
    """TV-20 (MP-32): after TV-19, `6F 0D` answers `0D` and the position becomes (0, 0, 0)."""
    host = connect(open_target)
    tv19(host)
    host.exchange(hx("6F 0D"), CR)
    host.exchange(GET_POSITION, ZEROS + CR)
    # the origin back where it was: a real unit keeps it for the tests that follow
    host.exchange(X_250, CR, within=0.2)
    host.exchange(hx("6F 0D"), CR)


def test_tv_021_target_beyond_travel_is_clamped(open_target: OpenTarget) -> None:
    """TV-21 (MP-36, MP-29): X = 400,000 stops at the travel limit, 312,500, and answers `0D`
    (after 62.65 s: free in virtual time, on a daemon device time runs 200×)."""
    host = connect(open_target, scale=200)
    host.exchange(FAR_X, CR, within=62.65)
    host.exchange(GET_POSITION, position(312_500))


@pytest.mark.control
def test_tv_021_clamped_move_time(open_target: OpenTarget) -> None:
    """TV-21 (MP-36, MP-43): 312,500 µsteps = 12,500 µm at 200 µm/s + 0.15 s: `0D` at 62.65 s."""
    target, host, clock = frozen(open_target)
    begin(target, host, clock, FAR_X)
    expect_at(host, clock, 62.65, CR)
    host.exchange(GET_POSITION, hx("B4 C4 04 00") + bytes(8) + CR)


def test_tv_021_out_of_range_error4(open_target: OpenTarget) -> None:
    """TV-21 (MP-36): `out_of_range: error4` answers `34 0D` at once and nothing moves."""
    host = connect(open_target, overrides={"knobs": {"out_of_range": "error4"}})
    done = host.send(FAR_X)
    host.expect_at(hx("34 0D"), done + 2 * CHAR)
    host.exchange(GET_POSITION, ZEROS + CR)


@pytest.mark.control
def test_tv_022_mt800_translator(open_target: OpenTarget) -> None:
    """TV-22 (MP-28, MP-29, MP-63): on `mp285-mt800` X + 20,000 µsteps is 1000 µm (20 per µm):
    `0D` at 5.150 s; STEP_DIV/STEP_MUL are 20/5."""
    target, host, clock = frozen(open_target, "mp285-mt800")
    begin(target, host, clock, hx("6D 20 4E 00 00 00 00 00 00 00 00 00 00 0D"))
    expect_at(host, clock, 5.150, CR)
    assert show(host.status()[24:28]) == "14 00 05 00"


@pytest.mark.control
def test_tv_023_coarse_step_quantum(open_target: OpenTarget) -> None:
    """TV-23 (MP-42): `coarse_step_quantum_usteps: 5` at low resolution: a move to X = 12 goes to
    10 (0.4 µm at 200 µm/s + 0.15 s: `0D` at 0.152 s)."""
    target, host, clock = frozen(open_target, overrides={"knobs": {"coarse_step_quantum_usteps": 5}})
    begin(target, host, clock, hx("6D 0C 00 00 00 00 00 00 00 00 00 00 00 0D"))
    expect_at(host, clock, 0.152, CR)
    host.exchange(GET_POSITION, position(10))


def velocity_case(
    open_target: OpenTarget,
    frame: str,
    reply: str,
    xspeed: str,
    byte15: int,
    profile: str = "mp285",
    overrides: dict[str, Any] | None = None,
) -> None:
    """Send a `V` frame, check its reply, then the status's XSPEED (28-29) and FLAGS_2 (15)."""
    host = connect(open_target, profile, overrides)
    host.exchange(hx(frame), hx(reply))
    status = host.status()
    assert (show(status[28:30]), status[15]) == (xspeed, byte15)


@pytest.mark.parametrize(
    ("profile", "frame", "xspeed", "byte15"),
    [("mp285", "56 09 83 0D", "09 83", 0x7C), ("mp285a", "56 B8 0B 0D", "B8 0B", 0x78)],
)
def test_tv_024_velocity_word_in_status(
    open_target: OpenTarget, profile: str, frame: str, xspeed: str, byte15: int
) -> None:
    """TV-24 (MP-37, MP-61, MP-62): 777 µm/s high resolution: XSPEED `09 83`, STEP_MODE set (FLAGS_2
    `7C`); on `mp285a` 3000 µm/s low: XSPEED `B8 0B`, FLAGS_2 `78`."""
    velocity_case(open_target, frame, "0D", xspeed, byte15, profile)


@pytest.mark.parametrize(
    ("overrides", "reply", "xspeed", "byte15"),
    [
        (None, "0D 0D", "1E 85", 0x7C),
        ({"knobs": {"velocity_over_limit": "error4"}}, "34 0D 0D", "C8 00", 0x78),
    ],
    ids=["clamp", "error4"],
)
def test_tv_025_big_endian_word(
    open_target: OpenTarget, overrides: dict[str, Any] | None, reply: str, xspeed: str, byte15: int
) -> None:
    """TV-25 (MP-41, MP-39): a CR LF host sending 1000 big-endian, `56 03 E8 0D 0A`: the device reads
    `E803`, high resolution at 26,627 µm/s, clamped to 1310 (`1E 85`), plus a CR for the LF. With
    `velocity_over_limit: error4`: `34 0D 0D` and XSPEED stays `C8 00`."""
    velocity_case(open_target, "56 03 E8 0D 0A", reply, xspeed, byte15, overrides=overrides)


def test_tv_026_high_resolution_over_the_limit(open_target: OpenTarget) -> None:
    """TV-26 (MP-41, MP-39): bit 15 + 6000 is clamped to 1310 at high resolution: `1E 85`."""
    velocity_case(open_target, "56 70 97 0D", "0D", "1E 85", 0x7C)


@pytest.mark.parametrize(
    ("frame", "xspeed", "byte15"), [("56 E8 83 0D", "E8 83", 0x7C), ("56 E8 03 0D", "E8 03", 0x78)]
)
def test_tv_027_bit_15_taken_literally(open_target: OpenTarget, frame: str, xspeed: str, byte15: int) -> None:
    """TV-27 (MP-41): a host that sets bit 15 for "coarse 1000" gets high resolution at 1000 µm/s
    (`E8 83`); its "fine 1000" is low resolution (`E8 03`)."""
    velocity_case(open_target, frame, "0D", xspeed, byte15)


@pytest.mark.parametrize(
    ("profile", "frame", "xspeed"),
    [
        ("mp285", "56 70 17 0D", "70 17"),
        ("mp285a", "56 70 17 0D", "B8 0B"),
        ("mp285", "56 0D 00 0D", "0D 00"),
    ],
    ids=["mp285-6000", "mp285a-6000", "cr-data-byte"],
)
def test_tv_028_low_resolution_limits(open_target: OpenTarget, profile: str, frame: str, xspeed: str) -> None:
    """TV-28 (MP-38, MP-18): 6000 µm/s low is within the MP-285's 6550 limit and clamped to the
    MP-285A's 3000; 13 µm/s, whose low byte is `0D`, is data."""
    velocity_case(open_target, frame, "0D", xspeed, 0x78, profile)


def test_tv_029_speed_zero(open_target: OpenTarget) -> None:
    """TV-29 (MP-40): at speed 0 a move never ends on its own: no reply for 5 s (on a daemon device
    time runs 20×), then ^C: `3D`, `0D`; nothing moved."""
    host = connect(open_target, scale=20)
    host.exchange(hx("56 00 00 0D"), CR)
    host.send(X_250)
    host.quiet(5.0)
    host.exchange(hx("03"), hx("3D 0D"), within=0.15)
    host.exchange(GET_POSITION, ZEROS + CR)


@pytest.mark.control
def test_tv_029_speed_zero_interrupt_times(open_target: OpenTarget) -> None:
    """TV-29 (MP-40, MP-48): ^C at 5 s answers `3D` at once and `0D` at 5.15 s."""
    target, host, clock = frozen(open_target)
    host.exchange(hx("56 00 00 0D"), CR)
    begin(target, host, clock, X_250)
    clock.to(5.0)
    assert target.get("state") == "MOVING"
    host.exchange(hx("03"), hx("3D"))
    expect_at(host, clock, 5.15, CR)
    host.exchange(GET_POSITION, ZEROS + CR)
