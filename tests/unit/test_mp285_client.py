"""The MP-285 thin client (protocols/clients/mp285.py) against the device model on a manual clock.

`FakeSerial` gives the client pyserial's blocking semantics over the model: `read(n)` lets device
time run until n bytes have arrived or `timeout` device seconds have passed, so every exchange,
however long the move, is exact and instant. It has no modem-line attributes: touching RTS/DTR
would raise.
"""

from __future__ import annotations

from typing import Any

import pytest
import serial

from protocols.clients import mp285 as client
from protocols.clients.mp285 import (
    BadCommand,
    BufferOverrun,
    FrameError,
    MoveInterrupted,
    MoveOutstanding,
    Mp285,
    Mp285Error,
    NoReply,
    SpOverrun,
    UnexpectedReply,
    error_for,
)
from protocols.mp285 import Vector, encode_position
from tests.unit.mp285.harness import Bench

DUMP_A = bytes.fromhex(
    "40 00 02 04 07 00 63 00 63 00 14 00 88 13 01 78 70 17 10 27 50 00 00 00 19 00 04 00 C8 00 54 01"
)


class FakeSerial:
    """The subset of `serial.Serial` the client uses, wired to a `Bench` (the host's side of the
    model's line, with pacing in both directions)."""

    baudrate = 9600
    bytesize = serial.EIGHTBITS
    parity = serial.PARITY_NONE
    stopbits = serial.STOPBITS_ONE

    def __init__(self, bench: Bench) -> None:
        self.bench = bench
        self.timeout: float | None = 1.0
        self.is_open = True
        self.written = bytearray()
        self._input = bytearray()

    def write(self, data: bytes) -> int:
        self.written += data
        self.bench.write(bytes(data))
        return len(data)

    def read(self, size: int = 1) -> bytes:
        assert self.timeout is not None, "a blocking read without timeout would hang the test"
        deadline = self.bench.now + self.timeout
        while len(self._input) < size:
            self._input += self.bench.take()
            due = self._next_due()
            if len(self._input) >= size or due is None or due > deadline:
                break
            self.bench.run(max(due, self.bench.now))
        if len(self._input) < size:
            self.bench.run(deadline)
            self._input += self.bench.take()
        data, self._input = bytes(self._input[:size]), self._input[size:]
        return data

    def _next_due(self) -> float | None:
        bench = self.bench
        due = [
            t
            for t in (bench.rx.next_due(), bench.device.next_deadline(), bench.tx.next_due())
            if t is not None
        ]
        return min(due) if due else None

    def close(self) -> None:
        self.is_open = False

    def take_written(self) -> bytes:
        data = bytes(self.written)
        self.written.clear()
        return data


def make(profile: str = "mp285", overrides: dict[str, Any] | None = None, **options: Any) -> Mp285:
    return Mp285(FakeSerial(Bench(profile, overrides)), **options)  # type: ignore[arg-type]


def fake(stage: Mp285) -> FakeSerial:
    assert isinstance(stage.port, FakeSerial)
    return stage.port


def device_state(stage: Mp285) -> dict[str, Any]:
    return fake(stage).bench.snapshot()


# ---- errors ------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("code", "cls"),
    [
        (0x30, SpOverrun),
        (0x31, FrameError),
        (0x32, BufferOverrun),
        (0x34, BadCommand),
        (0x38, MoveInterrupted),
        (0x3C, MoveInterrupted),  # '<' = '8' | '4' (MP-19)
        (0x39, MoveInterrupted),
    ],
)
def test_error_digits_map_to_typed_exceptions(code: int, cls: type[Mp285Error]) -> None:
    """MP-19: every error digit raises its own exception class, carrying the digit received."""
    error = error_for(code, "m")
    assert type(error) is cls
    assert error.code == code
    assert f"error '{chr(code)}'" in str(error)


# ---- opening -----------------------------------------------------------------------------------------


def test_open_uses_the_device_line_settings(monkeypatch: pytest.MonkeyPatch) -> None:
    """MP-1, MP-2: 8 data bits always; RTS/CTS only when asked (the MP-285A's USB port)."""
    calls: list[tuple[tuple[Any, ...], dict[str, Any]]] = []
    monkeypatch.setattr(serial, "Serial", lambda *args, **kwargs: calls.append((args, kwargs)) or object())
    stage = Mp285.open("/dev/ttyUSB0", rtscts=True, model="mp285a", timeout=2.0)
    assert stage.model == "mp285a" and stage.timeout == 2.0
    (args, kwargs) = calls[0]
    assert args == ("/dev/ttyUSB0", 9600)
    assert kwargs == {"bytesize": 8, "parity": "N", "stopbits": 1, "rtscts": True, "timeout": 2.0}


def test_unknown_model_or_stage_is_refused() -> None:
    with pytest.raises(ValueError, match="model"):
        make(model="mp286")
    with pytest.raises(ValueError, match="stage"):
        make(stage="mt900")


# ---- queries, units, settings ------------------------------------------------------------------------


def test_position_and_units_per_stage() -> None:
    """MP-28: 25 µsteps per µm, or 20 on an MT-800's X and Y."""
    stage = make()
    assert stage.position() == (0, 0, 0)
    assert fake(stage).take_written() == b"c\r"
    assert stage.to_usteps((1.0, -2.0, 0.04)) == (25, -50, 1)
    mt800 = make("mp285-mt800", stage="mt800")
    assert mt800.to_usteps((1.0, -2.0, 0.04)) == (20, -40, 1)
    assert mt800.to_um((20, 25, 25)) == (1.0, 1.25, 1.0)


def test_position_with_cr_bytes_in_the_data() -> None:
    """MP-10, MP-31: a position whose bytes include 0D is read by count, not up to the first CR."""
    far_origin = make(overrides={"stage": {"origin_usteps_from_bot": [4909237, 4888762, 16460893]}})
    assert far_origin.position() == (-4596737, -4576262, -16148393)  # TV-17
    stage = make()
    stage.move_to(13, 3341, -243)  # TV-7
    assert stage.position() == (13, 3341, -243)


def test_status_is_the_dataclass_and_tracks_velocity() -> None:
    """MP-60, MP-61: the status block decodes; its XSPEED is the velocity the client then tracks."""
    stage = make()
    assert stage.velocity is None
    status = stage.status()
    assert status.pack() == DUMP_A
    assert (status.version, status.step_div, status.step_mul) == (340, 25, 4)
    assert stage.velocity == client.Velocity(200, False)


def test_set_velocity_tracks_the_clamped_word() -> None:
    """MP-37 ... MP-39: the device reduces a speed over the limit of its model and resolution."""
    stage = make()
    stage.set_velocity(777, high=True)
    assert fake(stage).take_written() == bytes.fromhex("56 09 83 0D")
    assert stage.velocity == client.Velocity(777, True)
    stage.set_velocity(6000, high=True)
    assert stage.velocity == client.Velocity(1310, True) == stage.status().velocity
    mp285a = make("mp285a", model="mp285a")
    mp285a.set_velocity(6000)
    assert mp285a.velocity == client.Velocity(3000, False) == mp285a.status().velocity


def test_velocity_refused_by_the_device_keeps_the_tracked_word() -> None:
    """MP-39 `velocity_over_limit: error4`: '4' raises and the old word stays in force."""
    stage = make(overrides={"knobs": {"velocity_over_limit": "error4"}})
    stage.set_velocity(1000)
    with pytest.raises(BadCommand):
        stage.set_velocity(7000)
    assert stage.velocity == client.Velocity(1000, False) == stage.status().velocity


def test_modes_origin_and_refresh() -> None:
    """MP-32, MP-33, MP-74: each answers a lone CR; the mode is tracked client-side."""
    stage = make()
    assert stage.mode is None
    stage.relative()
    assert stage.mode == "relative" and device_state(stage)["mode"] == "relative"
    stage.absolute()
    assert stage.mode == "absolute" and device_state(stage)["mode"] == "absolute"
    stage.move_to(250, 0, 0)
    stage.set_origin()
    assert stage.position() == (0, 0, 0)
    stage.refresh()
    assert device_state(stage)["display"][0] == "X:+0.00 Y:+0.00 Z:+0.00"
    assert (
        fake(stage).take_written()
        == b"b\ra\rc\rs\r" + bytes.fromhex("6D FA 00 00 00") + bytes(8) + b"\ro\rc\rn\r"
    )


# ---- moves -------------------------------------------------------------------------------------------


def test_first_move_sets_absolute_mode_then_sends_targets() -> None:
    """MP-33, MP-34: the client cannot read the mode, so it sets it before its first move."""
    stage = make()
    stage.set_velocity(1000)
    fake(stage).take_written()
    stage.move_to_um(10.0, -4.0, 0.48)
    assert fake(stage).take_written() == b"a\rc\r" + client.proto.Move(250, -100, 12).encode()
    assert stage.position_um() == (10.0, -4.0, 0.48)
    fake(stage).take_written()
    stage.move_by(-250, 100, 0)
    assert fake(stage).take_written() == b"c\r" + client.proto.Move(0, 0, 12).encode()


def test_relative_mode_moves_send_displacements() -> None:
    """MP-33: in relative mode `m` values are added to the position; move_to converts."""
    stage = make()
    stage.relative()
    stage.move_by(250, 0, -250)
    stage.move_to(0, 0, 0)
    assert fake(stage).take_written() == (
        b"b\rs\r"
        + client.proto.Move(250, 0, -250).encode()
        + b"c\r"
        + client.proto.Move(-250, 0, 250).encode()
    )
    assert stage.position() == (0, 0, 0)


def test_long_move_waits_for_its_computed_completion() -> None:
    """MP-43, MP-44: a 62.65 s move (clamped at the travel limit, MP-36) completes within the
    timeout derived from distance, speed and settle time."""
    stage = make()
    stage.absolute()
    stage.status()
    bench = fake(stage).bench
    start = bench.now
    stage.move_to(400_000, 0, 0)  # `c` (2 + 13 characters), then `m` (14), its CR (1)
    assert bench.now - start == pytest.approx(62.65 + 30 * 10 / 9600)
    assert stage.position() == (312_500, 0, 0)


def test_timeout_follows_the_tracked_speed() -> None:
    """The timeout is derived from the tracked speed: a device secretly slowed down (here by a `V`
    sent behind the client's back) makes the move overrun it."""
    stage = make()
    stage.set_velocity(200)
    fake(stage).bench.write(bytes.fromhex("56 01 00 0D"))  # 1 µm/s
    fake(stage).read(1)
    with pytest.raises(NoReply, match="0 of 1 bytes"):
        stage.move_to(250, 0, 0)
    assert stage.moving  # still outstanding: the host can halt it
    assert stage.interrupt() is True


def test_out_of_range_move_refused_by_the_device() -> None:
    """MP-36 `out_of_range: error4`: the move's reply is '4' and nothing moves."""
    stage = make(overrides={"knobs": {"out_of_range": "error4"}})
    with pytest.raises(BadCommand):
        stage.move_to(400_000, 0, 0)
    assert not stage.moving
    assert stage.position() == (0, 0, 0)


def test_move_values_must_fit_32_bits() -> None:
    stage = make()
    stage.relative()
    with pytest.raises(ValueError, match="32 bits"):
        stage.move_by(2**31, 0, 0)


def test_only_ctrl_c_while_a_move_is_outstanding() -> None:
    """MP-12: the client refuses other commands until the final reply has been read."""
    stage = make()
    stage.move_to(25_000, 0, 0, wait=False)
    assert stage.moving
    with pytest.raises(MoveOutstanding):
        stage.position()
    stage.wait()
    assert not stage.moving
    assert stage.position() == (25_000, 0, 0)


def test_speed_zero_move_can_only_be_interrupted() -> None:
    """MP-40: at speed 0 a move never ends: waiting is refused, ^C halts it (TV-29)."""
    stage = make()
    stage.set_velocity(0)
    with pytest.raises(ValueError, match="never ends"):
        stage.move_to(250, 0, 0)
    stage.move_to(250, 0, 0, wait=False)
    with pytest.raises(ValueError, match="never ends"):
        stage.wait()
    assert stage.interrupt() is True
    assert stage.position() == (0, 0, 0)


# ---- interrupts ---------------------------------------------------------------------------------------


def test_interrupt_while_idle() -> None:
    """MP-49: an idle ^C is answered with CR."""
    stage = make()
    assert stage.interrupt() is False
    assert fake(stage).take_written() == b"\x03"


def test_interrupt_halts_a_move() -> None:
    """MP-48, TV-31: `3D` at once, the move's CR after the settle time; the axes stop where they
    are."""
    stage = make()
    stage.move_to(25_000, 0, 0, wait=False)
    bench = fake(stage).bench
    bench.run(bench.now + 1.0)
    assert stage.interrupt() is True
    x, y, z = stage.position()
    assert 4_900 < x < 5_100 and (y, z) == (0, 0)


def test_interrupt_crossing_the_final_reply() -> None:
    """MP-49, TV-36: a ^C sent after the move ended gets an idle CR behind the move's CR."""
    stage = make()
    stage.move_to(250, 250, 250, wait=False)
    bench = fake(stage).bench
    bench.run(bench.now + 0.5)
    assert stage.interrupt() is False
    assert stage.position() == (250, 250, 250)


# ---- programs -----------------------------------------------------------------------------------------

PROGRAM = (Vector.move(250, 0, -250), Vector.pause(), Vector.move(0, 25_000, 0))


def test_program_download_upload_execute_continue() -> None:
    """MP-66 ... MP-70, TV-41: `k` answers at the pause, `e` runs on to the end."""
    stage = make()
    stage.download(1, PROGRAM)
    assert stage.upload(1) == PROGRAM
    stage.execute(1)
    assert stage.paused == 1
    assert stage.position() == (250, 0, -250)
    stage.continue_program()
    assert stage.paused is None
    assert stage.position() == (250, 25_000, -250)
    stage.continue_program()  # nothing paused: CR at once (MP-70)


def test_execute_uploads_an_unknown_program_to_size_its_timeout() -> None:
    """MP-72: a program downloaded by someone else is uploaded first; an empty slot runs at once."""
    stage = make()
    fake(stage).bench.write(client.proto.Download(3, PROGRAM[2:]).encode())
    assert fake(stage).read(1) == b"\r"
    stage.execute(3)
    assert stage.position() == (0, 25_000, 0)
    assert stage.upload(4) == ()
    stage.execute(4)
    assert fake(stage).take_written() == b"u\x03\rs\rk\x03\rc\ru\x04\rk\x04\r"


def test_interrupt_abandons_a_program() -> None:
    """MP-54, MP-71, TV-43: ^C during a program's move, or while it is paused, abandons it."""
    stage = make()
    stage.download(1, PROGRAM)
    stage.execute(1)
    stage.continue_program(wait=False)
    bench = fake(stage).bench
    bench.run(bench.now + 1.0)
    assert stage.interrupt() is True
    assert stage.paused is None
    stage.execute(1)
    assert stage.interrupt() is False
    assert stage.paused is None and device_state(stage)["program"] is None


def test_program_arguments_are_checked() -> None:
    stage = make()
    with pytest.raises(ValueError):
        stage.download(0, PROGRAM)
    with pytest.raises(ValueError):
        stage.download(1, ())
    with pytest.raises(BadCommand):
        stage.upload(11)


# ---- reset ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("nul", [False, True])
def test_reset_waits_out_the_deaf_time(nul: bool) -> None:
    """MP-55 ... MP-58: no reply (or one NUL); the next command is not lost; defaults restored."""
    stage = make(overrides={"knobs": {"reset_emits_nul": nul}})
    stage.set_velocity(777, high=True)
    stage.relative()
    stage.reset()
    assert (stage.mode, stage.velocity) == ("absolute", None)
    assert stage.position() == (0, 0, 0)
    assert stage.status().xspeed == 0x00C8


def test_reset_with_unexpected_bytes() -> None:
    stage = make()
    fake(stage).bench.write(b"c\r")  # someone else's query: its reply arrives during the reset
    with pytest.raises(UnexpectedReply):
        stage.reset()


# ---- replies ---------------------------------------------------------------------------------------------


def test_error_reply_in_place_of_a_data_reply() -> None:
    """MP-19, MP-21: `34 0D` instead of a 13-byte position is recognised by the silence after it."""
    stage = make()
    fake(stage).bench.write(b"z")  # a stray byte: the next `c` frame is discarded, then '4'
    with pytest.raises(BadCommand):
        stage.position()
    assert stage.position() == (0, 0, 0)


def test_data_that_starts_like_an_error_reply() -> None:
    """MP-10: X = 0x0D34 starts with `34 0D`, the form of error '4', and is still a position."""
    stage = make()
    stage.move_to(0x0D34, 0, 0)
    assert stage.position() == (0x0D34, 0, 0)
    assert encode_position(0x0D34, 0, 0)[:2] == b"4\r"


def test_no_reply_names_what_arrived() -> None:
    stage = make()
    fake(stage).bench.control("crash", signature="silent")
    with pytest.raises(NoReply, match="nothing"):
        stage.position()


def test_crashed_unit_is_unexpected() -> None:
    """MP-77: a crashed unit's '0' bytes are neither a reply nor an error reply."""
    stage = make()
    fake(stage).bench.control("crash", signature="zero_char")
    with pytest.raises(UnexpectedReply):
        stage.set_origin()


def test_interrupt_crossing_an_error_reply() -> None:
    """MP-36, MP-49: a program stopped by an unreachable vector (`out_of_range: error4`) answers
    '4'; a ^C crossing that reply gets an idle CR, and the '4' is raised."""
    stage = make(overrides={"knobs": {"out_of_range": "error4"}})
    stage.download(1, (Vector.move(250, 0, 0), Vector.move(400_000, 0, 0)))
    stage.execute(1, wait=False)
    bench = fake(stage).bench
    bench.run(bench.now + 0.5)
    with pytest.raises(BadCommand):
        stage.interrupt()
    assert not stage.moving
    assert stage.position() == (250, 0, 0)
