"""TV-6 ... TV-17: framing, stray bytes, error replies and positions (MP-8 ... MP-31)."""

from __future__ import annotations

import pytest

from tests.conformance.mp285.wire import (
    CHAR,
    CR,
    DUMP_A,
    GET_POSITION,
    ZEROS,
    Host,
    OpenTarget,
    connect,
    hx,
    position,
)

#: TV-7: target (13, 3341, -243), whose bytes include 0D; 3341 µsteps = 133.64 µm at 200 µm/s
CR_PAYLOAD = hx("6D 0D 00 00 00 0D 0D 00 00 0D FF FF FF 0D")
CR_PAYLOAD_TIME = 3341 / 25 / 200 + 0.15
#: TV-8: X = 3, the `03` is data
CTRL_C_PAYLOAD = hx("6D 03 00 00 00 00 00 00 00 00 00 00 00 0D")
CTRL_C_PAYLOAD_TIME = 3 / 25 / 200 + 0.15


def test_tv_006_position_at_power_on(open_target: OpenTarget) -> None:
    """TV-6 (MP-13, MP-27, MP-35): `63 0D` gives twelve `00` and `0D`."""
    connect(open_target).exchange(GET_POSITION, ZEROS + CR)


def test_tv_007_payload_bytes_equal_to_cr(open_target: OpenTarget) -> None:
    """TV-7 (MP-8, MP-10, MP-31): the parser never looks for CR inside a frame; the position reply
    containing `0D` bytes is read by count."""
    host = connect(open_target)
    host.exchange(CR_PAYLOAD, CR, within=CR_PAYLOAD_TIME)
    host.exchange(GET_POSITION, hx("0D 00 00 00 0D 0D 00 00 0D FF FF FF 0D"))


def assert_move_reply_time(host: Host, frame: bytes, seconds: float) -> None:
    done = host.send(frame)
    host.expect_at(CR, done + seconds + CHAR, within=seconds)


@pytest.mark.timing
def test_tv_007_move_reply_time(open_target: OpenTarget) -> None:
    """TV-7 (MP-43, MP-44): the move's `0D` at 0.818 s (133.64 µm at 200 µm/s + 0.15 s)."""
    assert_move_reply_time(connect(open_target), CR_PAYLOAD, CR_PAYLOAD_TIME)


def test_tv_008_ctrl_c_byte_inside_a_payload_is_data(open_target: OpenTarget) -> None:
    """TV-8 (MP-9): `03` inside a payload is data: the move to X = 3 runs and answers `0D`."""
    host = connect(open_target)
    host.exchange(CTRL_C_PAYLOAD, CR, within=CTRL_C_PAYLOAD_TIME)
    host.exchange(GET_POSITION, position(3))


@pytest.mark.timing
def test_tv_008_move_reply_time(open_target: OpenTarget) -> None:
    """TV-8 (MP-43, MP-44): the move's `0D` at 0.1506 s (3 µsteps at 200 µm/s + 0.15 s)."""
    assert_move_reply_time(connect(open_target), CTRL_C_PAYLOAD, CTRL_C_PAYLOAD_TIME)


@pytest.mark.parametrize("timing", [pytest.param("realistic", marks=pytest.mark.smoke), "fast"])
def test_tv_009_two_commands_in_one_write(open_target: OpenTarget, timing: str) -> None:
    """TV-9 (MP-12): `73 0D 63 0D` in one write: the 33 status bytes, then the 13 position bytes,
    whether the line is paced or not (`timing: fast`)."""
    connect(open_target, timing=timing).exchange(hx("73 0D 63 0D"), DUMP_A + ZEROS + CR)


def test_tv_010_no_inter_byte_timeout(open_target: OpenTarget) -> None:
    """TV-10 (MP-25): `63`, ten seconds of silence, `0D`: the 13 position bytes. On the emulator
    device time runs 50× (silence is silence at any speed)."""
    host = connect(open_target, scale=50)
    host.send(hx("63"))
    host.quiet(10.0)
    host.exchange(CR, ZEROS + CR)


@pytest.mark.parametrize(
    ("frame", "reply"),
    [
        ("73 0D 0A", DUMP_A + CR),
        pytest.param("63 0D 0A", ZEROS + CR + CR, marks=pytest.mark.smoke),
        ("61 0D 0A", CR + CR),
    ],
    ids=["s", "c", "a"],
)
def test_tv_011_cr_lf_host_gets_one_more_cr(open_target: OpenTarget, frame: str, reply: bytes) -> None:
    """TV-11 (MP-20): a host ending commands with CR LF (bytes one character time, about 1 ms,
    apart) gets one CR more for the LF: 34, 14 and 2 bytes, and nothing else."""
    host = connect(open_target)
    host.exchange(hx(frame), reply)
    host.quiet(0.05)


@pytest.mark.parametrize(
    ("frame", "reply"),
    [("73 0D 0A", DUMP_A), ("63 0D 0A", ZEROS + CR), ("61 0D 0A", CR)],
    ids=["s", "c", "a"],
)
def test_tv_011_stray_terminator_ignored(open_target: OpenTarget, frame: str, reply: bytes) -> None:
    """TV-11 (MP-20): `stray_terminator_reply: ignore`: 33, 13 and 1 bytes, the LF unanswered."""
    host = connect(open_target, overrides={"knobs": {"stray_terminator_reply": "ignore"}})
    host.exchange(hx(frame), reply)
    host.quiet(0.05)


@pytest.mark.parametrize(("frame", "reply"), [("0D", "0D"), ("0A", "0D"), ("0D 0D 0D", "0D 0D 0D")])
def test_tv_011_lone_terminators(open_target: OpenTarget, frame: str, reply: str) -> None:
    """TV-11 (MP-20): a lone CR or LF between frames is answered with CR, each one."""
    host = connect(open_target)
    host.exchange(hx(frame), hx(reply))
    host.quiet(0.05)


@pytest.mark.parametrize(
    "frame", [pytest.param("43 0D", marks=pytest.mark.smoke), "52 0D", "76 0D", "78 79 7A 0D", "00 0D"]
)
def test_tv_012_unknown_commands(open_target: OpenTarget, frame: str) -> None:
    """TV-12 (MP-21, MP-19, MP-14, MP-59): another family's `C`, the interposer's `R`, lower-case
    `v`, several bad bytes, a NUL: discarded through the CR, then `34 0D` once, as the CR arrives."""
    host = connect(open_target)
    done = host.send(hx(frame))
    host.expect_at(hx("34 0D"), done + 2 * CHAR)
    host.quiet(0.05)


def test_tv_013_bad_terminator(open_target: OpenTarget) -> None:
    """TV-13 (MP-22): `63 63 0D` gives `34 0D` as its CR arrives. After `63 0A` (a Unix newline)
    nothing comes; the next `63 0D` is swallowed by the discarding, and its CR releases `34 0D`."""
    host = connect(open_target)
    done = host.send(hx("63 63 0D"))
    host.expect_at(hx("34 0D"), done + 2 * CHAR)
    host.send(hx("63 0A"))
    host.quiet(0.1)
    done = host.send(GET_POSITION)
    host.expect_at(hx("34 0D"), done + 2 * CHAR)
    host.exchange(GET_POSITION, ZEROS + CR)


def test_tv_014_buffer_overrun(open_target: OpenTarget) -> None:
    """TV-14 (MP-23): `71` then 64 × `41`, no CR: `32 0D` when the 65th byte arrives, not before;
    the CR that ends the discarding owes nothing; `63 0D` is then answered normally."""
    host = connect(open_target)
    host.send(hx("71") + b"A" * 63)
    host.quiet(0.05)
    host.exchange(b"A", hx("32 0D"))
    host.send(CR)
    host.quiet(0.05)
    host.exchange(GET_POSITION, ZEROS + CR)


@pytest.mark.smoke
@pytest.mark.timing
def test_tv_014_overrun_reply_time(open_target: OpenTarget) -> None:
    """TV-14 (MP-23): the `32 0D` is sent as the 65th byte is processed."""
    host = connect(open_target)
    done = host.send(hx("71") + b"A" * 64)
    host.expect_at(hx("32 0D"), done + 2 * CHAR)


def test_tv_015_eight_byte_longs(open_target: OpenTarget) -> None:
    """TV-15 (MP-26, MP-22): a host packing (250, 500, -11) as 8-byte longs: byte 13 (`00`) sits in
    the terminator position, so `34 0D` comes when the 26th byte arrives and nothing moves. A host
    reading one byte leaves the `0D` pending."""
    frame = hx("6D FA 00 00 00 00 00 00 00 F4 01 00 00 00 00 00 00 F5 FF FF FF FF FF FF FF 0D")
    host = connect(open_target)
    host.send(frame[:-1])
    host.quiet(0.05)
    done = host.send(frame[-1:])
    host.expect_at(b"4", done + CHAR)
    host.expect_at(CR, done + 2 * CHAR)
    host.exchange(GET_POSITION, ZEROS + CR)


def test_tv_016_eight_byte_longs_with_a_cr_byte(open_target: OpenTarget) -> None:
    """TV-16 (MP-26): the same host with Z = 13: discarding ends at byte 17 (Z's `0D`), `34 0D`;
    byte 18 (`00`) is an unknown command, discarded through byte 25: `34 0D` again, each as the
    byte that ends it arrives. No motion."""
    frame = hx("6D FA 00 00 00 00 00 00 00 F4 01 00 00 00 00 00 00 0D 00 00 00 00 00 00 00 0D")
    host = connect(open_target)
    done = host.send(frame)
    host.expect_at(hx("34 0D"), done - 8 * CHAR + 2 * CHAR)
    host.expect_at(hx("34 0D"), done + 2 * CHAR)
    host.quiet(0.05)
    host.exchange(GET_POSITION, ZEROS + CR)


def test_tv_017_positions_far_outside_travel(open_target: OpenTarget) -> None:
    """TV-17 (MP-30, MP-31): with the origin far from the axes, `63 0D` gives the reply captured
    from a real MP-285, (-4,596,737, -4,576,262, -16,148,393)."""
    host = connect(open_target, overrides={"stage": {"origin_usteps_from_bot": [4909237, 4888762, 16460893]}})
    host.exchange(GET_POSITION, hx("FF DB B9 FF FA 2B BA FF 57 98 09 FF 0D"))
