"""Test vectors TV-1 ... TV-49 (docs/mp285.md), driven on the sans-I/O model with a manual clock.

Times: the host frame that starts each vector is processed (its last byte) at T0 = 1 s, so "@0.200"
in a vector is T0 + 0.200 here. Device emissions are compared with their exact due instants.
"""

from __future__ import annotations

import pytest

from emulator.device import LineSettings
from protocols.mp285 import Download, Execute, Move, Vector, encode_position
from tests.unit.mp285.harness import CHAR, Bench, hexs

T0 = 1.0
ZEROS = " ".join(["00"] * 12)
DUMP_A = "40 00 02 04 07 00 63 00 63 00 14 00 88 13 01 78 70 17 10 27 50 00 00 00 19 00 04 00 C8 00 54 01 0D"
DUMP_B = "62 03 01 01 04 00 14 00 63 00 05 00 88 13 01 78 C4 09 88 13 50 00 00 00 19 00 04 00 DC 05 2E 01 0D"
TEN_UM = Move(250, 250, 250).encode()  # TV-18's +10 µm per axis
LONG_X = Move(25_000, 0, 0).encode()  # TV-31's 1000 µm on X, 5 s at 200 µm/s


def pos(x: int, y: int = 0, z: int = 0) -> str:
    return hexs(encode_position(x, y, z))


def at(t: float, *data: str) -> list[tuple[float, str]]:
    return [(round(t, 6), d) for d in data]


def status_of(bench: Bench) -> bytes:
    bench.take()
    bench.write(b"s\r")
    bench.run(bench.now + 0.1)
    reply = bench.take()
    bench.emissions()
    assert len(reply) == 33
    return reply


def position_of(bench: Bench) -> str:
    bench.take()
    bench.write(b"c\r")
    bench.run(bench.now + 0.1)
    bench.emissions()
    return hexs(bench.take())


# ---- TV-1, TV-2: status dumps ------------------------------------------------------------------------


def test_tv_001_status_dump_a_and_line_pacing() -> None:
    """TV-1 (MP-60, MP-65, MP-11, MP-3)."""
    bench = Bench("mp285")
    bench.write(b"s\r", done_at=T0)
    bench.run(T0 + 0.1)
    assert bench.emissions() == at(T0, DUMP_A)
    timed = bench.take_timed()
    assert hexs(bytes(b for _, b in timed)) == DUMP_A
    assert timed[-1][0] - T0 == pytest.approx(33 * CHAR)  # 34.4 ms after the first byte starts
    assert timed[-1][0] - timed[0][0] == pytest.approx(32 * CHAR)


def test_tv_002_status_dump_b() -> None:
    """TV-2 (MP-65, MP-63, MP-2): mp285a-v302 and mp285a byte-exact (25/4, as units report);
    mp285a-qr differs in STEP_DIV/STEP_MUL (the quick reference's 400/400)."""
    bench = Bench("mp285a-v302")
    assert bench.host is not None and bench.host.rtscts
    assert hexs(status_of(bench)) == DUMP_B
    assert hexs(status_of(Bench("mp285a"))) == DUMP_B
    quick_reference = hexs(status_of(Bench("mp285a-qr")))
    assert quick_reference == DUMP_B.replace("19 00 04 00 DC", "90 01 90 01 DC")


# ---- TV-3 ... TV-5: line mismatches --------------------------------------------------------------------


def record_chars(bench: Bench) -> list[tuple[int, bool]]:
    """Spy on the characters the device's receiver decodes."""
    seen: list[tuple[int, bool]] = []
    original = bench.device._on_char

    def spy(byte: int, framing_error: bool, t: float) -> None:
        seen.append((byte, framing_error))
        original(byte, framing_error, t)

    bench.device._on_char = spy  # type: ignore[method-assign]
    return seen


def test_tv_003_faster_host_is_garbled_to_one_byte() -> None:
    """TV-3 (MP-1, MP-4, MP-5, MP-6): a 19200-baud host's `63 0D` reaches the device as `91`."""
    host = LineSettings(19200, None, None, 1, False, False)
    bench = Bench(host=host)
    seen = record_chars(bench)
    bench.write(b"c\r", at=T0)
    bench.run(T0 + 1)
    assert seen == [(0x91, False)]
    assert bench.take() == b""
    assert bench.device.mismatch_effect(host) == "traffic will be garbled (line_mismatch=garble)"


def test_tv_003_slower_host_gives_framing_errors_and_no_reply() -> None:
    """TV-3: a 4800-baud host's `63 0D` decodes as 1E (FE), 66 (FE), 80; its CR is never a CR."""
    bench = Bench(host=LineSettings(4800, None, None, 1, False, False))
    seen = record_chars(bench)
    bench.write(b"c\r", at=T0)
    bench.run(T0 + 1)
    assert seen == [(0x1E, True), (0x66, True), (0x80, False)]
    assert bench.take() == b""


def test_tv_003_stop_bits_only_and_ignore_give_normal_replies() -> None:
    """TV-3: 9600 8N2 is reported but corrupts nothing; `line_mismatch: ignore` passes bytes."""
    two_stop = LineSettings(9600, None, None, 2, False, False)
    bench = Bench(host=two_stop)
    bench.write(b"c\r", at=T0)
    bench.run(T0 + 0.1)
    assert hexs(bench.take()) == pos(0)
    assert "corrupts nothing" in bench.device.mismatch_effect(two_stop)
    fast = LineSettings(19200, None, None, 1, False, False)
    bench = Bench(overrides={"knobs": {"line_mismatch": "ignore"}}, host=fast)
    bench.write(b"c\r", at=T0)
    bench.run(T0 + 0.1)
    assert hexs(bench.take()) == pos(0)
    assert bench.device.mismatch_effect(fast) == "traffic passes unchanged (line_mismatch=ignore)"


@pytest.mark.parametrize("frame", [b"c\r", b"zc\r"])
def test_tv_004_parity_host_gets_frame_error_garbled_back(frame: bytes) -> None:
    """TV-4 (MP-6, MP-24): an 8E1 host's `63` has a framing error at the device -> `31 0D`, which the
    host decodes as 00 (framing error) and C3 (parity error); '1' replaces a pending '4'."""
    bench = Bench(host=LineSettings(9600, 8, "even", 1, False, False))
    seen = record_chars(bench)
    bench.write(frame, at=T0)
    bench.run(T0 + 0.1)
    assert seen[-2:] == [(0x63, True), (0x0D, False)]
    assert bench.take() == b"\x00\xc3"


def usb_after_v200(rtscts: bool) -> Bench:
    bench = Bench("mp285a", host=LineSettings(9600, None, None, 1, rtscts, False))
    bench.write(b"V\xc8\x00\r", at=0.1)
    bench.run(0.5)
    assert bench.take() == b"\r"
    bench.write(LONG_X, done_at=T0)
    bench.emissions()
    return bench


def test_tv_005_usb_without_rtscts_loses_input_while_busy() -> None:
    """TV-5 (MP-7, MP-2): the ^C is the kept byte, `63 0D` are lost, then '0' after the final CR."""
    bench = usb_after_v200(rtscts=False)
    bench.write(b"\x03c\r", done_at=T0 + 1 + 2 * CHAR)
    bench.run(T0 + 2)
    assert bench.emissions() == at(T0 + 1, "3D") + at(T0 + 1.15, "0D") + at(T0 + 1.15 + CHAR, "30 0D")
    assert "lost" in bench.device.mismatch_effect(LineSettings(9600, None, None, 1, False, False))


def test_tv_005_lone_ctrl_c_still_works_without_rtscts() -> None:
    """TV-5: a lone ^C during the move works normally."""
    bench = usb_after_v200(rtscts=False)
    bench.write(b"\x03", done_at=T0 + 1)
    bench.run(T0 + 2)
    assert bench.emissions() == at(T0 + 1, "3D") + at(T0 + 1.15, "0D")


def test_tv_005_with_rtscts_behaves_as_tv32() -> None:
    """TV-5: with RTS/CTS nothing is lost."""
    bench = usb_after_v200(rtscts=True)
    bench.write(b"\x03c\r", done_at=T0 + 1 + 2 * CHAR)
    bench.run(T0 + 2)
    assert bench.emissions() == at(T0 + 1, "3D") + at(T0 + 1 + 2 * CHAR, pos(5000)) + at(T0 + 1.15, "0D")


# ---- TV-6 ... TV-17: framing, stray bytes, positions --------------------------------------------------


def test_tv_006_position_at_power_on() -> None:
    """TV-6 (MP-13, MP-27, MP-35)."""
    bench = Bench()
    bench.write(b"c\r", done_at=T0)
    bench.run(T0 + 0.1)
    assert bench.emissions() == at(T0, f"{ZEROS} 0D")


def test_tv_007_payload_bytes_equal_to_cr() -> None:
    """TV-7 (MP-8, MP-10, MP-31): target (13, 3341, -243) whose bytes include 0D."""
    frame = bytes.fromhex("6D 0D 00 00 00 0D 0D 00 00 0D FF FF FF 0D")
    bench = Bench()
    bench.write(frame, done_at=T0)
    bench.run(T0 + 2)
    assert bench.emissions() == at(T0 + 3341 / 25 / 200 + 0.15, "0D")
    assert position_of(bench) == "0D 00 00 00 0D 0D 00 00 0D FF FF FF 0D"


def test_tv_008_ctrl_c_byte_inside_payload_is_data() -> None:
    """TV-8 (MP-9)."""
    bench = Bench()
    bench.write(Move(3, 0, 0).encode(), done_at=T0)
    bench.run(T0 + 1)
    assert bench.emissions() == at(T0 + 0.1506, "0D")


@pytest.mark.parametrize("paced", [True, False])
def test_tv_009_two_commands_in_one_write(paced: bool) -> None:
    """TV-9 (MP-12): replies come in order, 46 bytes."""
    bench = Bench(paced=paced)
    bench.write(b"s\rc\r", at=T0)
    bench.run(T0 + 1)
    assert hexs(bench.take()) == f"{DUMP_A} {ZEROS} 0D"


def test_tv_010_no_inter_byte_timeout() -> None:
    """TV-10 (MP-25)."""
    bench = Bench()
    bench.write(b"c", at=T0)
    bench.write(b"\r", at=T0 + 10)
    bench.run(T0 + 11)
    assert hexs(bench.take()) == f"{ZEROS} 0D"


def write_per_ms(bench: Bench, data: bytes, start: float) -> None:
    for i, byte in enumerate(data):
        bench.write(bytes((byte,)), at=start + i * 0.001)


@pytest.mark.parametrize(
    ("reply", "lengths"), [("cr", (34, 14, 2)), ("ignore", (33, 13, 1))], ids=["cr", "ignore"]
)
def test_tv_011_cr_lf_host(reply: str, lengths: tuple[int, int, int]) -> None:
    """TV-11 (MP-20): the LF after each command is answered with one more CR (or ignored)."""
    bench = Bench(overrides={"knobs": {"stray_terminator_reply": reply}})
    for frame, length in zip((b"s\r\n", b"c\r\n", b"a\r\n"), lengths, strict=True):
        write_per_ms(bench, frame, bench.now)
        bench.run(bench.now + 0.2)
        out = bench.take()
        assert len(out) == length
        assert out.endswith(b"\r\r" if reply == "cr" else b"\r")


@pytest.mark.parametrize(("sent", "expected"), [(b"\r", b"\r"), (b"\n", b"\r"), (b"\r\r\r", b"\r\r\r")])
def test_tv_011_lone_terminators(sent: bytes, expected: bytes) -> None:
    """TV-11 (MP-20)."""
    bench = Bench()
    bench.write(sent, at=T0)
    bench.run(T0 + 0.1)
    assert bench.take() == expected


@pytest.mark.parametrize("frame", ["43 0D", "52 0D", "76 0D", "78 79 7A 0D", "00 0D"])
def test_tv_012_unknown_commands(frame: str) -> None:
    """TV-12 (MP-21, MP-19, MP-14, MP-59): one `34 0D` per bad frame, at its CR."""
    data = bytes.fromhex(frame)
    bench = Bench()
    bench.write(data, done_at=T0)
    bench.run(T0 + 0.1)
    assert bench.emissions() == at(T0, "34 0D")


def test_tv_013_bad_terminator_and_unix_newline() -> None:
    """TV-13 (MP-22)."""
    bench = Bench()
    bench.write(b"cc\r", done_at=T0)
    bench.run(T0 + 0.1)
    assert bench.emissions() == at(T0, "34 0D")
    bench.write(b"c\n", at=T0 + 1)
    bench.run(T0 + 2)
    assert bench.take_timed()[-1][0] < T0 + 1  # nothing for `63 0A`
    bench.write(b"c\r", done_at=T0 + 3)
    bench.run(T0 + 3.1)
    assert bench.emissions() == at(T0 + 3, "34 0D")


def test_tv_014_buffer_overrun_while_discarding() -> None:
    """TV-14 (MP-23): `32 0D` as the 65th byte arrives; its CR then owes nothing."""
    bench = Bench()
    bench.write(b"q" + b"A" * 64, done_at=T0)
    bench.run(T0 + 0.1)
    assert bench.emissions() == at(T0, "32 0D")
    bench.write(b"\r", at=T0 + 0.2)
    bench.run(T0 + 0.3)
    assert bench.emissions() == []
    bench.write(b"c\r", at=T0 + 0.4)
    bench.run(T0 + 0.5)
    assert hexs(bench.take()) == f"32 0D {ZEROS} 0D"


def test_tv_015_eight_byte_longs_are_a_bad_frame() -> None:
    """TV-15 (MP-26, MP-22): byte 13 sits in terminator position; one `34 0D` at the host's CR."""
    frame = bytes.fromhex("6D FA 00 00 00 00 00 00 00 F4 01 00 00 00 00 00 00 F5 FF FF FF FF FF FF FF 0D")
    bench = Bench()
    bench.write(frame, done_at=T0)
    bench.run(T0 + 1)
    assert bench.emissions() == at(T0, "34 0D")
    assert bench.snapshot()["position"]["usteps"] == {"X": 0, "Y": 0, "Z": 0}


def test_tv_016_discarded_cr_ends_discarding_early() -> None:
    """TV-16 (MP-26): Z's low byte 0D ends DISCARDING; the rest is a second bad frame."""
    frame = bytes.fromhex("6D FA 00 00 00 00 00 00 00 F4 01 00 00 00 00 00 00 0D 00 00 00 00 00 00 00 0D")
    bench = Bench()
    bench.write(frame, done_at=T0)
    bench.run(T0 + 1)
    assert bench.emissions() == at(T0 - 8 * CHAR, "34 0D") + at(T0, "34 0D")


def test_tv_017_origin_far_outside_travel() -> None:
    """TV-17 (MP-30, MP-31)."""
    bench = Bench(overrides={"stage": {"origin_usteps_from_bot": [4909237, 4888762, 16460893]}})
    assert position_of(bench) == "FF DB B9 FF FA 2B BA FF 57 98 09 FF 0D"


# ---- TV-18 ... TV-29: motion and velocity ---------------------------------------------------------------


@pytest.mark.parametrize(
    ("knobs", "done"),
    [({}, 0.200), ({"axis_motion": "sequential"}, 0.300), ({"accel_um_s2": 1000}, 0.350)],
    ids=["simultaneous", "sequential", "accel"],
)
def test_tv_018_move_timing(knobs: dict, done: float) -> None:
    """TV-18 (MP-43, MP-44, MP-47, MP-45)."""
    bench = Bench(overrides={"knobs": knobs})
    bench.write(TEN_UM, done_at=T0)
    bench.run(T0 + 1)
    assert bench.emissions() == at(T0 + done, "0D")
    if not knobs:  # the host's round trip: 14 characters out, the move, one character back
        arrival = bench.take_timed()[-1][0]
        assert arrival - (T0 - 14 * CHAR) == pytest.approx(0.216, abs=0.001)


def test_tv_019_relative_then_absolute() -> None:
    """TV-19 (MP-33, MP-35)."""
    bench = Bench()
    bench.write(b"b\r", done_at=T0)
    back = Move(-250, 0, 0).encode()
    bench.write(back, done_at=T0 + 0.1)
    bench.run(T0 + 1)
    assert bench.emissions() == at(T0, "0D") + at(T0 + 0.3, "0D")
    assert position_of(bench) == pos(-250)
    bench.write(b"a\r", done_at=T0 + 2)
    bench.write(back, done_at=T0 + 3)
    bench.run(T0 + 4)
    assert bench.emissions() == at(T0 + 2, "0D") + at(T0 + 3.15, "0D")


def test_tv_020_set_origin() -> None:
    """TV-20 (MP-32)."""
    bench = Bench()
    bench.write(Move(-250, 0, 0).encode(), done_at=T0)
    bench.run(T0 + 1)
    bench.write(b"o\r", done_at=T0 + 2)
    bench.run(T0 + 2.1)
    assert bench.emissions()[-1] == (T0 + 2, "0D")
    assert position_of(bench) == f"{ZEROS} 0D"


def test_tv_021_target_beyond_travel_is_clamped() -> None:
    """TV-21 (MP-36, MP-29)."""
    bench = Bench()
    bench.write(Move(400_000, 0, 0).encode(), done_at=T0)
    bench.run(T0 + 70)
    assert bench.emissions() == at(T0 + 62.65, "0D")
    assert position_of(bench) == "B4 C4 04 00 " + " ".join(["00"] * 8) + " 0D"


def test_tv_021_out_of_range_error4() -> None:
    """TV-21 with `out_of_range: error4`: `34 0D` at once, no motion."""
    bench = Bench(overrides={"knobs": {"out_of_range": "error4"}})
    bench.write(Move(400_000, 0, 0).encode(), done_at=T0)
    bench.run(T0 + 1)
    assert bench.emissions() == at(T0, "34 0D")
    assert position_of(bench) == f"{ZEROS} 0D"


def test_tv_022_mt800_factors() -> None:
    """TV-22 (MP-28, MP-29, MP-63): 20,000 µsteps = 1000 µm on an MT-800."""
    bench = Bench("mp285-mt800")
    bench.write(Move(20_000, 0, 0).encode(), done_at=T0)
    bench.run(T0 + 6)
    assert bench.emissions() == at(T0 + 5.15, "0D")
    assert status_of(bench)[24:28] == bytes.fromhex("14 00 05 00")


def test_tv_023_coarse_step_quantum() -> None:
    """TV-23 (MP-42)."""
    bench = Bench(overrides={"knobs": {"coarse_step_quantum_usteps": 5}})
    bench.write(Move(12, 0, 0).encode(), done_at=T0)
    bench.run(T0 + 1)
    assert bench.emissions() == at(T0 + 0.152, "0D")
    assert position_of(bench) == pos(10)


@pytest.mark.parametrize(
    ("profile", "frame", "xspeed", "flags_2"),
    [("mp285", "56 09 83 0D", "09 83", 0x7C), ("mp285a", "56 B8 0B 0D", "B8 0B", 0x78)],
)
def test_tv_024_velocity_word_in_status(profile: str, frame: str, xspeed: str, flags_2: int) -> None:
    """TV-24 (MP-37, MP-61, MP-62)."""
    bench = Bench(profile)
    bench.write(bytes.fromhex(frame), at=T0)
    bench.run(T0 + 0.1)
    assert bench.take() == b"\r"
    status = status_of(bench)
    assert status[15] == flags_2
    assert hexs(status[28:30]) == xspeed


@pytest.mark.parametrize(
    ("mode", "reply", "xspeed"), [("clamp", "0D 0D", "1E 85"), ("error4", "34 0D 0D", "C8 00")]
)
def test_tv_025_big_endian_velocity(mode: str, reply: str, xspeed: str) -> None:
    """TV-25 (MP-41, MP-39): `56 03 E8` is E803: high resolution, 26,627 µm/s."""
    bench = Bench(overrides={"knobs": {"velocity_over_limit": mode}})
    write_per_ms(bench, bytes.fromhex("56 03 E8 0D 0A"), T0)
    bench.run(T0 + 0.1)
    assert hexs(bench.take()) == reply
    status = status_of(bench)
    assert hexs(status[28:30]) == xspeed
    assert status[15] == (0x7C if mode == "clamp" else 0x78)


@pytest.mark.parametrize(
    ("profile", "frame", "xspeed"),
    [
        ("mp285", "56 70 97 0D", "1E 85"),  # TV-26
        ("mp285", "56 E8 83 0D", "E8 83"),  # TV-27 coarse 1000 with bit 15: high resolution
        ("mp285", "56 E8 03 0D", "E8 03"),  # TV-27
        ("mp285", "56 70 17 0D", "70 17"),  # TV-28: 6000 low on the MP-285
        ("mp285a", "56 70 17 0D", "B8 0B"),  # TV-28: clamped to 3000 on the MP-285A
        ("mp285", "56 0D 00 0D", "0D 00"),  # TV-28: data byte 0D
    ],
)
def test_tv_026_to_28_velocity_outliers(profile: str, frame: str, xspeed: str) -> None:
    """TV-26, TV-27, TV-28 (MP-41, MP-39, MP-38, MP-18)."""
    bench = Bench(profile)
    bench.write(bytes.fromhex(frame), at=T0)
    bench.run(T0 + 0.1)
    assert bench.take() == b"\r"
    assert hexs(status_of(bench)[28:30]) == xspeed


def test_tv_029_speed_zero_never_ends() -> None:
    """TV-29 (MP-40)."""
    bench = Bench()
    bench.write(b"V\x00\x00\r", at=0.1)
    bench.run(0.5)
    bench.emissions()
    bench.write(Move(250, 0, 0).encode(), done_at=T0)
    bench.run(T0 + 4.9)
    assert bench.emissions() == []
    bench.write(b"\x03", done_at=T0 + 5)
    bench.run(T0 + 6)
    assert bench.emissions() == at(T0 + 5, "3D") + at(T0 + 5.15, "0D")
    assert position_of(bench) == f"{ZEROS} 0D"


# ---- TV-30 ... TV-39: interrupts and reset ----------------------------------------------------------------


@pytest.mark.parametrize(
    ("sent", "expected"), [(b"\x03", "0D"), (b"\x03\r", "0D 0D"), (b"\x03\r\n", "0D 0D 0D")]
)
def test_tv_030_idle_ctrl_c(sent: bytes, expected: str) -> None:
    """TV-30 (MP-49)."""
    bench = Bench()
    bench.write(sent, at=T0)
    bench.run(T0 + 0.1)
    assert hexs(bench.take()) == expected


def long_move(overrides: dict | None = None, profile: str = "mp285") -> Bench:
    bench = Bench(profile, overrides=overrides)
    bench.write(LONG_X, done_at=T0)
    bench.run(T0 + 0.5)
    return bench


def test_tv_031_ctrl_c_during_move() -> None:
    """TV-31 (MP-48, MP-46, MP-14)."""
    bench = long_move()
    bench.write(b"\x03", done_at=T0 + 1)
    bench.run(T0 + 2)
    assert bench.emissions() == at(T0 + 1, "3D") + at(T0 + 1.15, "0D")
    assert position_of(bench) == pos(5000)


def test_tv_032_ctrl_c_then_query_in_one_write() -> None:
    """TV-32 (MP-48, MP-52): 14 bytes by @1.020, the 15th (`0D`) at @1.150."""
    bench = long_move()
    bench.write(b"\x03c\r", done_at=T0 + 1 + 2 * CHAR)
    bench.run(T0 + 1.020)
    assert hexs(bench.take()) == "3D " + pos(5000)
    bench.run(T0 + 2)
    assert bench.emissions() == at(T0 + 1, "3D") + at(T0 + 1 + 2 * CHAR, pos(5000)) + at(T0 + 1.15, "0D")
    assert bench.take_timed() == [(pytest.approx(T0 + 1.15 + CHAR), 0x0D)]


@pytest.mark.parametrize(
    ("reply", "expected"),
    [
        ("cr", at(T0 + 1 + CHAR, pos(5000)) + at(T0 + 1.15, "0D")),
        ("error8", at(T0 + 1 + CHAR, pos(5000)) + at(T0 + 1.15, "38 0D")),
        ("error8_4", at(T0 + 1.15, "3C 0D")),
    ],
)
def test_tv_033_query_interrupts_move(reply: str, expected: list) -> None:
    """TV-33 (MP-51, MP-52, MP-53)."""
    bench = long_move({"knobs": {"move_interrupt_reply": reply}})
    bench.write(b"c\r", done_at=T0 + 1 + CHAR)
    bench.run(T0 + 2)
    assert bench.emissions() == expected
    assert bench.snapshot()["position"]["usteps"]["X"] == 5000
    if reply == "error8_4":
        assert bench.snapshot()["display"][1] == "ERR 4"


def test_tv_034_second_move_waits_for_the_first_final_reply() -> None:
    """TV-34 (MP-51, MP-52)."""
    bench = long_move()
    bench.write(Move(0, 0, 0).encode(), done_at=T0 + 1 + 13 * CHAR)
    bench.run(T0 + 3)
    assert bench.emissions() == at(T0 + 1.15, "0D") + at(T0 + 2.3, "0D")
    assert position_of(bench) == f"{ZEROS} 0D"


def test_tv_035_every_ctrl_c_is_acknowledged() -> None:
    """TV-35 (MP-48)."""
    bench = long_move()
    bench.write(b"\x03", done_at=T0 + 1)
    bench.write(b"\x03", done_at=T0 + 1.05)
    bench.run(T0 + 2)
    assert bench.emissions() == at(T0 + 1, "3D") + at(T0 + 1.05, "3D") + at(T0 + 1.15, "0D")


@pytest.mark.parametrize("when", [0.201, 0.160])
def test_tv_036_reply_order_depends_on_timing(when: float) -> None:
    """TV-36 (MP-49, MP-52): after the final CR the ^C is idle; in STOPPING it is acknowledged."""
    bench = Bench()
    bench.write(TEN_UM, done_at=T0)
    bench.write(b"\x03c\r", done_at=T0 + when + 2 * CHAR)
    bench.run(T0 + 1)
    query = pos(250, 250, 250)
    if when > 0.2:
        expected = at(T0 + 0.2, "0D") + at(T0 + when, "0D") + at(T0 + when + 2 * CHAR, query)
    else:
        expected = at(T0 + when, "3D") + at(T0 + when + 2 * CHAR, query) + at(T0 + 0.2, "0D")
    assert bench.emissions() == expected
    assert len(bench.take()) == 15


def test_tv_037_lf_after_move_does_not_interrupt() -> None:
    """TV-37 (MP-50): the LF waits and is answered after the final CR."""
    bench = Bench(paced=False)  # the vector's exact instants, unpaced
    write_per_ms(bench, TEN_UM + b"\n", T0 - 0.013)
    bench.run(T0 + 1)
    assert bench.emissions() == at(T0 + 0.2, "0D", "0D")
    write_per_ms(bench, b"c\r\n", T0 + 2)
    bench.run(T0 + 3)
    assert bench.take()[-14:] == bytes.fromhex("FA 00 00 00 FA 00 00 00 FA 00 00 00 0D 0D")


def test_tv_037_terminators_interrupt_move() -> None:
    """TV-37 with `terminators_interrupt_move: true`: halt @0.001 at (5, 5, 5)."""
    bench = Bench(overrides={"knobs": {"terminators_interrupt_move": True}}, paced=False)
    write_per_ms(bench, TEN_UM + b"\n", T0 - 0.013)
    bench.run(T0 + 1)
    assert bench.emissions() == at(T0 + 0.151, "0D", "0D")
    assert position_of(bench) == pos(5, 5, 5)


@pytest.mark.parametrize("nul", [False, True])
def test_tv_038_reset(nul: bool) -> None:
    """TV-38 (MP-15, MP-55, MP-56, MP-57, MP-58)."""
    bench = Bench(overrides={"knobs": {"reset_emits_nul": nul}})
    bench.write(b"V\x09\x83\r", at=0.1)
    bench.write(b"b\r", at=0.2)
    bench.write(Move(100, 0, 0).encode(), at=0.3)
    bench.run(0.9)
    bench.take()
    bench.emissions()
    bench.write(b"r\r", done_at=T0)
    bench.write(b"c\r", at=T0 + 0.10)
    bench.run(T0 + 0.29)
    assert bench.emissions() == (at(T0, "00") if nul else [])
    bench.write(b"c\r", at=T0 + 0.30)
    bench.run(T0 + 0.4)
    assert bench.emissions() == at(T0 + 0.30 + 2 * CHAR, pos(100))
    status = status_of(bench)
    assert (hexs(status[28:30]), status[15]) == ("C8 00", 0x78)
    bench.write(Move(200, 0, 0).encode(), at=bench.now)
    bench.run(bench.now + 1)
    assert position_of(bench) == pos(200)  # absolute again: relative would give 300


def test_tv_039_reset_during_move() -> None:
    """TV-39 (MP-57): halt, final CR, then DEAF until @1.350."""
    bench = long_move()
    bench.write(b"r\r", done_at=T0 + 1 + CHAR)
    bench.write(b"c\r", done_at=T0 + 1.34)
    bench.run(T0 + 1.345)
    assert bench.emissions() == at(T0 + 1.15, "0D")
    bench.write(b"c\r", done_at=T0 + 1.36)
    bench.run(T0 + 1.5)
    assert bench.emissions() == at(T0 + 1.36, pos(5000))


# ---- TV-40 ... TV-49: status flags, programs, display, faults ------------------------------------------


@pytest.mark.parametrize(
    ("knobs", "after_a", "after_b"),
    [
        ({}, 0x40, 0x40),
        ({"flags_bit5_tracks_move_mode": True}, 0x40, 0x60),
        ({"flags_bit5_tracks_move_mode": True, "flags_bit5_relative_is_set": False}, 0x60, 0x40),
    ],
)
def test_tv_040_flags_bit5(knobs: dict, after_a: int, after_b: int) -> None:
    """TV-40 (MP-64, MP-34)."""
    bench = Bench(overrides={"knobs": knobs})
    for command, flags in ((b"b\r", after_b), (b"a\r", after_a)):
        bench.write(command, at=bench.now)
        bench.run(bench.now + 0.1)
        assert status_of(bench)[0] == flags


TV41_DOWNLOAD = bytes.fromhex("64 01 02 D0 07 00 00 FA 00 00 00 00 00 00 00 06 FF FF FF") + bytes(16) + b"\r"


def downloaded(overrides: dict | None = None) -> Bench:
    bench = Bench(overrides=overrides)
    bench.write(TV41_DOWNLOAD, done_at=T0)
    bench.run(T0 + 0.1)
    assert bench.emissions() == at(T0, "0D")
    bench.take()
    return bench


def test_tv_041_program_download_upload_execute_continue() -> None:
    """TV-41 (MP-66, MP-16, MP-17, MP-14, MP-72, MP-68, MP-70, MP-69)."""
    assert Download(1, (Vector.move(250, 0, -250), Vector.pause())).encode() == TV41_DOWNLOAD
    bench = downloaded()
    bench.write(b"u\x01\r", at=T0 + 0.2)
    bench.run(T0 + 0.5)
    assert bench.take() == TV41_DOWNLOAD[2:-1] + b"\r"
    bench.write(b"k\x01\r", done_at=T0 + 1)
    bench.run(T0 + 1.5)
    assert bench.emissions()[-1:] == at(T0 + 1.2, "0D")
    assert position_of(bench) == "FA 00 00 00 00 00 00 00 06 FF FF FF 0D"
    for _ in range(2):
        bench.write(b"e\r", done_at=bench.now + 0.1)
        done = bench.now + 2 * CHAR
        bench.run(bench.now + 0.2)
        assert bench.emissions()[-1:] == at(done, "0D")
    bench.write(b"k\x01\r", done_at=T0 + 3)
    bench.run(T0 + 4)
    assert bench.emissions() == at(T0 + 3.2, "0D")
    assert position_of(bench) == "F4 01 00 00 00 00 00 00 0C FE FF FF 0D"


def test_tv_041_follow_mode_vectors_are_absolute_targets() -> None:
    """TV-41 with `program_vectors: follow_mode`: the second run is already there."""
    bench = downloaded({"knobs": {"program_vectors": "follow_mode"}})
    for start, done in ((T0 + 1, 0.2), (T0 + 3, 0.15)):
        bench.write(Execute(1).encode(), done_at=start)
        bench.run(start + 1)
        assert bench.emissions()[-1:] == at(start + done, "0D")
    assert position_of(bench) == "FA 00 00 00 00 00 00 00 06 FF FF FF 0D"


@pytest.mark.parametrize(
    ("frame", "reply"),
    [
        ("6B 00 0D", "34 0D"),
        ("6B 0B 0D", "34 0D"),
        ("75 0B 0D", "34 0D"),
        ("64 01 00 0D", "34 0D"),
        ("64 0B 01 D0 07 00 00" + " 00" * 12 + " 0D", "34 0D"),
        ("64 01 01 00 00 07 D0" + " 00" * 12 + " 0D", "34 0D"),
        ("75 02 0D", "00 0D"),
        ("6B 02 0D", "0D"),
    ],
)
def test_tv_042_program_validation(frame: str, reply: str) -> None:
    """TV-42 (MP-67, MP-72): errors after the whole frame; nothing stored."""
    data = bytes.fromhex(frame)
    bench = Bench()
    bench.write(data, done_at=T0)
    bench.run(T0 + 0.1)
    assert bench.emissions() == at(T0, reply)
    assert bench.snapshot()["programs"] == {}


def test_tv_043_interrupt_abandons_the_program() -> None:
    """TV-43 (MP-54, MP-71)."""
    bench = Bench()
    bench.write(Download(1, (Vector.move(25_000, 0, 0), Vector.move(0, 100, 0))).encode(), at=0.1)
    bench.write(Execute(1).encode(), done_at=T0)
    bench.write(b"\x03", done_at=T0 + 1)
    bench.run(T0 + 2)
    assert bench.emissions()[-2:] == at(T0 + 1, "3D") + at(T0 + 1.15, "0D")
    bench.write(b"e\r", done_at=T0 + 3)
    bench.run(T0 + 4)
    assert bench.emissions() == at(T0 + 3, "0D")
    assert bench.snapshot()["position"]["usteps"] == {"X": 5000, "Y": 0, "Z": 0}


def test_tv_043_ctrl_c_abandons_a_paused_program() -> None:
    """TV-43: after TV-41's k (paused) `c` works, ^C abandons, `e` answers at once."""
    bench = downloaded()
    bench.write(b"k\x01\r", done_at=T0 + 1)
    bench.run(T0 + 1.5)
    assert bench.snapshot()["state"] == "PAUSED"
    assert position_of(bench) == "FA 00 00 00 00 00 00 00 06 FF FF FF 0D"
    bench.write(b"\x03", done_at=T0 + 2)
    bench.write(b"e\r", done_at=T0 + 3)
    bench.run(T0 + 4)
    assert bench.emissions() == at(T0 + 2, "0D") + at(T0 + 3, "0D")
    assert bench.snapshot()["state"] == "IDLE"


@pytest.mark.parametrize(
    ("retention", "after_reset", "after_power_cycle"),
    [("power_cycle", True, False), ("reset", False, False), ("always", True, True)],
)
def test_tv_044_program_retention(retention: str, after_reset: bool, after_power_cycle: bool) -> None:
    """TV-44 (MP-73)."""
    bench = downloaded({"knobs": {"program_retention": retention}})
    stored = TV41_DOWNLOAD[2:-1] + b"\r"
    bench.write(b"r\r", at=T0 + 0.5)
    bench.run(T0 + 0.9)
    bench.write(b"u\x01\r", at=bench.now)
    bench.run(bench.now + 0.1)
    assert bench.take() == (stored if after_reset else b"\x00\r")
    bench.control("power_cycle")
    bench.run(bench.now + 1.1)
    bench.write(b"u\x01\r", at=bench.now)
    bench.run(bench.now + 0.1)
    assert bench.take() == (stored if after_power_cycle else b"\x00\r")


def test_tv_045_display_refreshes_only_on_n() -> None:
    """TV-45 (MP-74, MP-75)."""
    bench = Bench()
    bench.write(TEN_UM, done_at=T0)
    bench.run(T0 + 1)
    assert bench.snapshot()["display"] == ["X:+0.00 Y:+0.00 Z:+0.00", ""]
    bench.write(b"n\r", done_at=T0 + 2)
    bench.run(T0 + 2.1)
    assert bench.emissions()[-1] == (T0 + 2, "0D")
    assert bench.snapshot()["display"] == ["X:+10.00 Y:+10.00 Z:+10.00", ""]
    bench.write(b"x\r", at=T0 + 3)
    bench.run(T0 + 3.1)
    assert bench.snapshot()["display"][1] == "ERR 4"


def test_tv_046_crash_and_power_cycle() -> None:
    """TV-46 (MP-77, MP-78, MP-76)."""
    bench = Bench()
    bench.run(T0)
    bench.control("crash")
    assert bench.emissions() == at(T0, " ".join(["00"] * 16))
    bench.write(b"c\r", at=T0 + 0.1)
    bench.run(T0 + 0.2)
    assert bench.take() == bytes(16 + 2)
    bench.write(b"\r" * 400, at=T0 + 0.3)
    bench.run(T0 + 1)
    assert bench.take() == bytes(400)
    assert bench.snapshot()["state"] == "CRASHED"
    bench.control("power_cycle")
    bench.write(b"c\r", at=T0 + 1.5)
    bench.run(T0 + 1.9)
    assert bench.take() == b""
    bench.write(b"c\r", at=T0 + 2.1)
    bench.run(T0 + 2.2)
    assert hexs(bench.take()) == f"{ZEROS} 0D"


def test_tv_046_ctrl_c_recovery() -> None:
    """TV-46 with `crash_recovery: ctrl_c`."""
    bench = Bench(overrides={"knobs": {"crash_recovery": "ctrl_c"}})
    bench.run(T0)
    bench.control("crash")
    bench.run(T0 + 0.1)
    bench.take()
    bench.write(b"\x03", at=T0 + 0.2)
    bench.write(b"c\r", at=T0 + 0.3)
    bench.run(T0 + 0.4)
    assert hexs(bench.take()) == f"0D {ZEROS} 0D"


def test_tv_046_cr_burst_recovery() -> None:
    """MP-78 `cr_burst`: the 200th consecutive CR recovers (like a reset without DEAF)."""
    bench = Bench(overrides={"knobs": {"crash_recovery": "cr_burst"}})
    bench.run(T0)
    bench.control("crash", signature="zero_char")
    bench.write(b"\r" * 199 + b"x" + b"\r" * 200, at=T0 + 0.1)
    bench.write(b"c\r", at=T0 + 1)
    bench.run(T0 + 1.1)
    assert bench.take() == b"0" * (16 + 199 + 1 + 199) + encode_position(0, 0, 0)


def test_tv_047_roe_then_host_input_in_the_crash_window() -> None:
    """TV-47 (MP-79)."""
    bench = Bench(overrides={"knobs": {"roe_crash": True}})
    bench.run(T0)
    bench.control("roe", axis="X", clicks=1)
    bench.write(b"c\r", at=T0 + 0.3)
    bench.run(T0 + 0.4)
    assert hexs(bench.take()) == pos(7)
    bench.write(b"c\r", at=T0 + 0.7)
    bench.run(T0 + 0.8)
    assert bench.take() == bytes(18)
    assert bench.snapshot()["state"] == "CRASHED"


def test_tv_048_incomplete_frame_locks_up() -> None:
    """TV-48 (MP-80)."""
    bench = Bench(overrides={"knobs": {"lockup_incomplete_frame_s": 1.0}})
    bench.write(b"m\x01\x02", at=T0)
    bench.write(b"c\r", at=T0 + 1.5)
    bench.run(T0 + 2)
    assert bench.take() == b""
    assert bench.snapshot()["state"] == "LOCKED"
    bench.control("power_cycle")
    bench.write(b"c\r", at=T0 + 3)
    bench.run(T0 + 3.1)
    assert hexs(bench.take()) == f"{ZEROS} 0D"


def test_tv_049_query_does_not_interrupt() -> None:
    """TV-49 (MP-51, MP-46): `c` answered with the interpolated X = 5005, the move goes on."""
    bench = long_move({"knobs": {"query_interrupts_move": False}})
    bench.write(b"c\r", done_at=T0 + 1 + CHAR)
    bench.run(T0 + 6)
    assert bench.emissions() == at(T0 + 1 + CHAR, pos(5005)) + at(T0 + 5.15, "0D")
    assert position_of(bench) == pos(25_000)
