"""The MP-285 device model beyond the test vectors: §7 details, programs, serial line, control channel."""

from __future__ import annotations

import json

import pytest

from emulator.device import ControlError, DeviceServices, LineSettings
from emulator.profiles.profile import load_profile
from emulator.profiles.registry import family
from protocols.mp285 import Download, Execute, Move, Vector, encode_position
from tests.unit.mp285.harness import CHAR, Bench, hexs

T0 = 1.0
TEN_UM = Move(250, 250, 250).encode()
LONG_X = Move(25_000, 0, 0).encode()
HOST_19200 = LineSettings(19200, None, None, 1, False, False)


def at(t: float, *data: str) -> list[tuple[float, str]]:
    return [(round(t, 6), d) for d in data]


def pos(x: int, y: int = 0, z: int = 0) -> str:
    return hexs(encode_position(x, y, z))


def long_move(knobs: dict | None = None, profile: str = "mp285", host: object = None) -> Bench:
    bench = Bench(profile, {"knobs": knobs} if knobs else None) if host is None else Bench(profile, host=host)
    bench.write(LONG_X, done_at=T0)
    bench.run(T0 + 0.5)
    bench.emissions()
    return bench


# ---- the contract ----------------------------------------------------------------------------------


def test_outputs_are_stamped_with_their_due_instant_not_the_call_time() -> None:
    """device.py: a late `advance` still stamps the final reply at T_m + settle."""
    profile = load_profile("mp285")
    device = family("mp285").factory("d", profile, 0.0, DeviceServices())  # type: ignore[union-attr]
    device.receive(TEN_UM, 0.0)
    assert device.next_deadline() == pytest.approx(0.2)
    device.advance(5.0)
    (emission,) = device.take_output()
    assert (emission.due, emission.data) == (pytest.approx(0.2), b"\r")
    assert device.next_deadline() is None


def test_whole_chunks_and_single_bytes_give_the_same_replies() -> None:
    """MP-3: the model is correct whether the host delivers byte by byte or whole writes."""
    stream = b"s\rV\x09\x83\rb\r" + Download(2, (Vector.pause(),)).encode() + b"u\x02\rc\rzz\r\x03\r\n"
    outputs = []
    for paced in (True, False):
        bench = Bench(paced=paced)
        bench.write(stream, at=T0)
        bench.run(T0 + 2)
        outputs.append(bench.take())
    assert outputs[0] == outputs[1]
    assert outputs[0].endswith(b"\r\x01" + bytes(16) + b"\r" + encode_position(0, 0, 0) + b"4\r\r\r\r")


def test_snapshot_is_plain_data_and_observables_work() -> None:
    bench = Bench()
    bench.write(Download(3, (Vector.move(1, 2, 3),)).encode(), at=T0)
    bench.write(LONG_X, done_at=T0 + 1)
    bench.run(T0 + 2)
    snap = bench.snapshot()
    json.dumps(snap)
    assert snap["state"] == "MOVING"
    assert snap["position"]["usteps"]["X"] == 5000
    assert snap["position"]["um"]["X"] == 200.0
    assert snap["target_usteps"] == {"X": 25_000, "Y": 0, "Z": 0}
    assert snap["velocity"] == {"word": 200, "speed_um_s": 200, "resolution": "low"}
    assert snap["programs"] == {"3": [{"descriptor": 2000, "x": 1, "y": 2, "z": 3}]}
    assert snap["line"] == {
        "device": "9600 8N1",
        "host": "9600 8N1",
        "garbled": False,
        "input_unprotected": False,
    }
    assert bench.device.observe("display", bench.now) == ["X:+0.00 Y:+0.00 Z:+0.00", ""]
    with pytest.raises(ControlError):
        bench.device.observe("nonsense", bench.now)


def test_events() -> None:
    bench = Bench()
    bench.write(TEN_UM, done_at=T0)
    bench.run(T0 + 1)
    bench.control("crash")
    bench.control("power_cycle")
    bench.run(T0 + 3)
    names = [e["ev"] for e in bench.take_events()]
    assert names == ["move_started", "move_ended", "crashed", "power_cycle", "powered_on"]


# ---- §7: bytes during a move -------------------------------------------------------------------------


def test_status_during_stopping_is_answered_at_once() -> None:
    """MP-52."""
    bench = long_move()
    bench.write(b"c\r", done_at=T0 + 1 + CHAR)
    bench.write(b"s\r", done_at=T0 + 1.05)
    bench.run(T0 + 2)
    out = bench.emissions()
    assert [t for t, _ in out] == [round(T0 + 1 + CHAR, 6), T0 + 1.05, T0 + 1.15]
    assert out[1][1].endswith("C8 00 54 01 0D")


def test_held_frames_wait_for_the_final_reply_and_ctrl_c_does_not() -> None:
    """MP-52: after a held frame everything waits; a ^C in command position is acted on at once."""
    bench = long_move()
    bench.write(b"c\r", done_at=T0 + 1 + CHAR)
    bench.write(b"a\r", done_at=T0 + 1.05)
    bench.write(b"c\r", done_at=T0 + 1.08)
    bench.write(b"\x03", done_at=T0 + 1.1)
    bench.run(T0 + 2)
    assert bench.emissions() == (
        at(T0 + 1 + CHAR, pos(5000)) + at(T0 + 1.1, "3D") + at(T0 + 1.15, "0D", "0D", pos(5000))
    )


def test_error8_4_discards_the_interrupting_move() -> None:
    """MP-53 `error8_4`: the interrupting `m` is dropped through its CR; `3C 0D`; no second move."""
    bench = long_move({"move_interrupt_reply": "error8_4"})
    bench.write(Move(0, 0, 0).encode(), done_at=T0 + 1 + 13 * CHAR)
    bench.run(T0 + 4)
    assert bench.emissions() == at(T0 + 1.15, "3C 0D")
    assert bench.snapshot()["position"]["usteps"]["X"] == 5000


@pytest.mark.parametrize(
    ("knobs", "interrupting"),
    [({}, b"c\r"), ({"query_interrupts_move": False}, b"cx\r")],
)
def test_error8_4_drops_the_interrupting_frame_behind_held_input(knobs: dict, interrupting: bytes) -> None:
    """MP-53 `error8_4`, MP-52: behind a held LF (MP-50) the interrupting frame is still dropped
    through its CR; only the LF is answered after `3C 0D`."""
    bench = Bench(overrides={"knobs": {"move_interrupt_reply": "error8_4", **knobs}})
    bench.write(LONG_X + b"\n", done_at=T0 + CHAR)
    bench.run(T0 + 0.5)
    bench.write(interrupting, done_at=T0 + 1 + CHAR)  # the halting byte (`c`, or `x`) at T0 + 1
    bench.run(T0 + 2)
    assert bench.emissions() == at(T0 + 1.15, "3C 0D", "0D")
    assert bench.snapshot()["parser"] == "command"


def test_bad_terminator_interrupts_when_queries_do_not() -> None:
    """MP-51 with `query_interrupts_move: false`: only a bad terminator halts; the bad frame waits."""
    bench = long_move({"query_interrupts_move": False})
    bench.write(b"cc\r", done_at=T0 + 1 + 2 * CHAR)
    bench.run(T0 + 2)
    assert bench.emissions() == at(T0 + 1.15 + CHAR, "0D", "34 0D")
    assert bench.snapshot()["position"]["usteps"]["X"] == 5005


def test_sequential_axes_interpolate_in_their_own_slots() -> None:
    """MP-43, MP-46 with `axis_motion: sequential`."""
    bench = Bench(overrides={"knobs": {"axis_motion": "sequential"}})
    bench.write(TEN_UM, done_at=T0)
    bench.write(b"\x03", done_at=T0 + 0.075)
    bench.run(T0 + 1)
    assert bench.snapshot()["position"]["usteps"] == {"X": 250, "Y": 125, "Z": 0}


def test_acceleration_interpolates_along_the_profile() -> None:
    """MP-45, MP-46: triangular profile, half the distance at half the time."""
    bench = Bench(overrides={"knobs": {"accel_um_s2": 1000}})
    bench.write(TEN_UM, done_at=T0)
    bench.write(b"\x03", done_at=T0 + 0.05)
    bench.run(T0 + 1)
    assert bench.snapshot()["position"]["usteps"] == {"X": 31, "Y": 31, "Z": 31}  # 1.25 µm of 10


def test_zero_length_move_at_speed_zero_ends_after_settle() -> None:
    """MP-40."""
    bench = Bench()
    bench.write(b"V\x00\x00\r", at=0.1)
    bench.write(Move(0, 0, 0).encode(), done_at=T0)
    bench.run(T0 + 1)
    assert bench.emissions()[-1] == (T0 + 0.15, "0D")


# ---- programs ------------------------------------------------------------------------------------------


def test_k_reply_only_at_the_end() -> None:
    """MP-68 `k_reply_at_pause: false`: no reply at the pause; `e` answers at once, `k` at the end."""
    bench = Bench(overrides={"knobs": {"k_reply_at_pause": False}})
    program = (Vector.move(250, 0, 0), Vector.pause(), Vector.move(250, 0, 0))
    bench.write(Download(1, program).encode(), at=0.1)
    bench.run(0.5)
    bench.emissions()
    bench.write(Execute(1).encode(), done_at=T0)
    bench.run(T0 + 0.9)
    assert bench.emissions() == []
    assert bench.snapshot()["state"] == "PAUSED"
    bench.write(b"e\r", done_at=T0 + 1)
    bench.run(T0 + 2)
    assert bench.emissions() == at(T0 + 1, "0D") + at(T0 + 1.2, "0D")
    assert bench.snapshot()["position"]["usteps"]["X"] == 500


def test_program_out_of_range_with_error4() -> None:
    """MP-69, MP-36: a vector outside travel with `out_of_range: error4` ends the program with '4'."""
    bench = Bench(overrides={"knobs": {"out_of_range": "error4"}})
    bench.write(Download(1, (Vector.move(250, 0, 0), Vector.move(400_000, 0, 0))).encode(), at=0.1)
    bench.write(Execute(1).encode(), done_at=T0)
    bench.run(T0 + 1)
    assert bench.emissions()[-1] == (T0 + 0.2, "34 0D")
    assert bench.snapshot()["program"] is None


def test_ctrl_c_in_stopping_abandons_the_program() -> None:
    """MP-48, MP-54: the STOPPING end is unchanged but the next vector never runs."""
    bench = Bench()
    bench.write(Download(1, (Vector.move(250, 0, 0), Vector.move(250, 0, 0))).encode(), at=0.1)
    bench.write(Execute(1).encode(), done_at=T0)
    bench.write(b"\x03", done_at=T0 + 0.1)
    bench.run(T0 + 1)
    assert bench.emissions()[-2:] == at(T0 + 0.1, "3D") + at(T0 + 0.2, "0D")
    assert bench.snapshot()["position"]["usteps"]["X"] == 250


def test_commands_while_paused() -> None:
    """MP-71, MP-20: an `m` runs and the program stays paused; a stray CR is answered; `e` resumes."""
    bench = Bench()
    bench.write(Download(1, (Vector.pause(), Vector.move(0, 250, 0))).encode(), at=0.1)
    bench.write(Execute(1).encode(), done_at=T0)
    bench.write(Move(250, 0, 0).encode(), done_at=T0 + 1)
    bench.write(b"\r", done_at=T0 + 2)
    bench.write(b"e\r", done_at=T0 + 3)
    bench.run(T0 + 4)
    assert bench.emissions()[-4:] == at(T0, "0D") + at(T0 + 1.2, "0D") + at(T0 + 2, "0D") + at(T0 + 3.2, "0D")
    assert bench.snapshot()["position"]["usteps"] == {"X": 250, "Y": 250, "Z": 0}


def test_reset_abandons_a_paused_program() -> None:
    """MP-57."""
    bench = Bench()
    bench.write(Download(1, (Vector.pause(),)).encode(), at=0.1)
    bench.write(Execute(1).encode(), done_at=T0)
    bench.write(b"r\r", done_at=T0 + 1)
    bench.run(T0 + 2)
    assert bench.snapshot()["state"] == "IDLE"


# ---- serial line -------------------------------------------------------------------------------------


def test_garbled_traffic_both_ways_with_exact_times() -> None:
    """MP-6: a 19200-baud host's `44 00` reaches the device as a CR; the device's CR reaches the
    host as E6 80, each at the instant the host's receiver completes it."""
    bench = Bench(host=HOST_19200)
    assert bench.device.pace_line is False  # the model times the garbled line itself
    bench.write(b"\x44\x00", at=T0)
    bench.run(T0 + 0.1)
    device_cr = T0 + 19 / 19200  # the device's stop sample, inside the host's second byte
    assert bench.emissions() == at(device_cr + 9.5 / 19200, "E6") + at(device_cr + 19.5 / 19200, "80")
    assert bench.snapshot()["line"]["garbled"] is True


def test_garbled_bytes_in_flight_survive_crash_recovery() -> None:
    """MP-6, MP-78: an 8N2 host's `03 63 0D` in one write: the ^C recovers the unit and the `c`
    behind it, still on the wire then, is answered (a reset clears input received, not in flight)."""
    host = LineSettings(9600, None, None, 2, False, False)
    bench = Bench(overrides={"knobs": {"crash_recovery": "ctrl_c"}}, host=host)
    bench.control("crash", signature="silent")
    bench.write(b"\x03c\r", at=T0)
    bench.run(T0 + 0.1)
    assert bench.take() == b"\r" + encode_position(0, 0, 0)


def test_set_line_from_the_front_panel() -> None:
    """MP-1: the device's own settings change through the control channel; then the host mismatches."""
    bench = Bench()
    assert bench.control("set_line", baud=19200, stop_bits=2) == {"line": "19200 8N2"}
    assert bench.device.line_settings().baud == 19200
    assert bench.device.pace_line is False
    bench.write(b"c\r", at=T0)
    bench.run(T0 + 0.1)
    assert bench.take() != encode_position(0, 0, 0)
    for params in ({"baud": 14400}, {"parity": "mark"}, {"speed": 1}):
        with pytest.raises(ControlError):
            bench.control("set_line", **params)
    with pytest.raises(ControlError, match="fixed at 9600"):
        Bench("mp285a").control("set_line", baud=19200)


def test_mismatch_effects() -> None:
    """MP-5: the tail of the daemon's one-line warning."""
    rs232 = Bench().device
    assert "no handshake lines" in rs232.mismatch_effect(LineSettings(9600, None, None, 1, True, False))
    assert "XON/XOFF" in rs232.mismatch_effect(LineSettings(9600, None, None, 1, False, True))
    relaxed = Bench("mp285a", {"controller": {"require_rtscts": False}}).device
    assert relaxed.mismatch_effect(LineSettings(9600, None, None, 1, False, False)) == (
        "no input is lost (require_rtscts=false)"
    )


def test_usb_without_rtscts_overruns_while_replying() -> None:
    """MP-7: `73 0D 63 0D` in one write: `63` is kept, `0D` lost, then '0' once the status is sent."""
    bench = Bench("mp285a", host=LineSettings(9600, None, None, 1, False, False))
    bench.write(b"s\rc\r", done_at=T0 + 2 * CHAR)
    bench.run(T0 + 1)
    out = bench.emissions()
    assert len(out) == 2 and out[0][0] == T0
    assert out[1] == (round(T0 + 33 * CHAR, 6), "30 0D")
    assert bench.snapshot()["line"]["input_unprotected"] is True


def test_usb_without_rtscts_kept_byte_is_parsed_after_the_busy_period() -> None:
    """MP-7: a single byte sent while busy waits in the register and is parsed afterwards."""
    bench = Bench("mp285a", host=LineSettings(9600, None, None, 1, False, False))
    bench.write(b"s\r", done_at=T0)
    bench.write(b"c", done_at=T0 + 0.01)
    bench.write(b"\r", done_at=T0 + 0.1)
    bench.run(T0 + 1)
    assert bench.emissions()[-1] == (T0 + 0.1, pos(0))


# ---- faults and the control channel -----------------------------------------------------------------------


def test_power_cycle_during_a_move() -> None:
    """MP-76: motion stops where it is, no reply, silent and deaf for `power_on_s`."""
    bench = long_move()
    bench.run(T0 + 1)
    assert bench.control("power_cycle") == {"powered_at": T0 + 2}
    assert bench.snapshot()["state"] == "POWERING_ON"
    bench.write(b"c\r", at=T0 + 1.5)
    bench.run(T0 + 2.5)
    bench.write(b"c\r", at=T0 + 2.5)
    bench.run(T0 + 3)
    assert bench.emissions() == at(T0 + 2.5 + 2 * CHAR, pos(5000))


def test_crash_during_a_move_never_replies() -> None:
    """MP-77: motion stops and no pending reply is ever sent."""
    bench = long_move({"crash_signature": "silent"})
    bench.run(T0 + 1)
    bench.control("crash")
    bench.write(b"c\r", at=T0 + 2)
    bench.run(T0 + 10)
    assert bench.emissions() == []
    assert bench.snapshot()["position"]["usteps"]["X"] == 5000
    for signature in ("loud", ["nul"], {"nul": 1}):
        with pytest.raises(ControlError, match="signature must be one of"):
            bench.control("crash", signature=signature)


def test_roe_crash_uses_the_profile_signature() -> None:
    """MP-79, MP-77: an ROE crash sends `crash_signature`, not the signature of an earlier injected
    crash (a power cycle restores the power-on state, MP-76)."""
    bench = Bench(overrides={"knobs": {"roe_crash": True, "power_on_s": 0.1}})
    bench.control("crash", signature="zero_char")
    bench.control("power_cycle")
    bench.run(T0)
    bench.take()
    bench.control("roe", axis="X", clicks=1)
    bench.write(b"c", at=T0 + 0.7)
    bench.run(T0 + 0.8)
    assert bench.take() == bytes(17)


def test_lockup_while_discarding() -> None:
    """MP-80: any incomplete frame, bad ones included."""
    bench = Bench(overrides={"knobs": {"lockup_incomplete_frame_s": 0.5}})
    bench.write(b"zz", at=T0)
    bench.run(T0 + 1)
    assert bench.snapshot()["state"] == "LOCKED"
    assert bench.device.next_deadline() is None


def test_roe_moves_flags_and_display() -> None:
    """MP-79: clicks × ROE_VARI, clamped to travel; FLAGS bit 4 = last turn negative."""
    bench = Bench()
    result = bench.control("roe", axis="y", clicks=-3)
    assert result == {"position_usteps": {"X": 0, "Y": -21, "Z": 0}}
    assert bench.snapshot()["display"][0] == "X:+0.00 Y:-0.84 Z:+0.00"
    assert bench.snapshot()["status"].startswith("50 ")
    bench.control("roe", axis="X", clicks=1_000_000)
    assert bench.snapshot()["position"]["usteps"]["X"] == 312_500
    for params in ({"axis": "W", "clicks": 1}, {"axis": "X", "clicks": 1.5}, {"axis": "X"}):
        with pytest.raises(ControlError):
            bench.control("roe", **params)
    bench.write(LONG_X, at=bench.now)
    bench.run(bench.now + 0.5)
    with pytest.raises(ControlError, match="only while the controller is idle"):
        bench.control("roe", axis="X", clicks=1)
    with pytest.raises(ControlError, match="known: crash, power_cycle, roe, set_line"):
        bench.control("joystick")
