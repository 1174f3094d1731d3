"""TV-1 ... TV-5: status dumps and the serial line (MP-1 ... MP-7, MP-60 ... MP-65)."""

from __future__ import annotations

from typing import Any

import pytest
import serial

from protocols.mp285 import StatusBlock, Velocity
from tests.conformance.conftest import NO_PARITY, carries_parity
from tests.conformance.mp285.conftest import LogOf
from tests.conformance.mp285.wire import (
    CHAR,
    CR,
    DUMP_A,
    DUMP_B,
    GET_POSITION,
    GET_STATUS,
    LONG_X,
    ZEROS,
    Host,
    OpenTarget,
    connect,
    hx,
    show,
)


@pytest.mark.smoke
def test_tv_001_status_dump_a(open_target: OpenTarget) -> None:
    """TV-1 (MP-60, MP-65, MP-11): `73 0D` gives dump A of a real MP-285: VERSION 340, STEP_DIV and
    STEP_MUL 25/4, XSPEED 200 µm/s at low resolution, words least significant byte first."""
    host = connect(open_target)
    host.send(GET_STATUS)
    reply = host.read(33)
    assert show(reply) == show(DUMP_A)
    status = StatusBlock.unpack(reply)
    assert (status.version, status.step_div, status.step_mul) == (340, 25, 4)
    assert status.velocity == Velocity(200, high=False)


@pytest.mark.smoke
@pytest.mark.timing
def test_tv_001_status_reply_is_paced(open_target: OpenTarget) -> None:
    """TV-1 (MP-3, MP-11): the dump leaves as the `s` frame's CR is processed, one character per
    character time: the first byte completes one character time after the frame, the 33rd 34.4 ms
    after the first byte started."""
    host = connect(open_target)
    done = host.send(GET_STATUS)
    host.read(1)
    host.assert_at(host.now(), done + CHAR)
    host.read(32)
    host.assert_at(host.now(), done + 33 * CHAR)


@pytest.mark.parametrize(
    ("profile", "expected"),
    [
        ("mp285a-v302", DUMP_B),
        ("mp285a", DUMP_B),
        ("mp285a-qr", DUMP_B[:24] + hx("90 01 90 01") + DUMP_B[28:]),
    ],
    ids=["mp285a-v302", "mp285a", "mp285a-qr"],
)
def test_tv_002_status_dump_b(open_target: OpenTarget, profile: str, expected: bytes) -> None:
    """TV-2 (MP-65, MP-63, MP-2): an MP-285A host with RTS/CTS; `mp285a-v302` and `mp285a` give the
    real dump B byte for byte (STEP fields 25/4, as units report), `mp285a-qr` differs only in
    STEP_DIV/STEP_MUL (the quick reference's 400/400, nm per 10 µsteps, §0.1)."""
    host = connect(open_target, profile)
    assert host.port.rtscts
    host.send(GET_STATUS)
    assert show(host.read(33)) == show(expected)


@pytest.mark.parametrize(("baud", "error"), [(19200, "34"), (4800, "31")])
def test_tv_003_host_at_another_baud_gets_no_reply(open_target: OpenTarget, baud: int, error: str) -> None:
    """TV-3 (MP-1, MP-6): at 19200 baud `63 0D` reaches the device as the single byte `91`, at 4800
    as `1E` (framing error), `66` (framing error), `80`: no CR, so no reply. A CR sent at the right
    baud then ends that bad frame, with '4' after the unknown command `91` (MP-21) or '1' after the
    framing errors (MP-24), which shows what the device decoded."""
    host = connect(open_target, baudrate=baud)
    host.send(GET_POSITION)
    host.quiet(0.2)
    host.port.baudrate = 9600
    host.exchange(CR, hx(f"{error} 0D"))


def test_tv_003_two_stop_bits_corrupt_nothing(open_target: OpenTarget) -> None:
    """TV-3 (MP-6): only the first stop bit is checked, so a 9600 8N2 host gets normal replies."""
    host = connect(open_target, stopbits=serial.STOPBITS_TWO)
    host.exchange(GET_POSITION, ZEROS + CR)


def test_tv_003_line_mismatch_ignore_passes_bytes(open_target: OpenTarget) -> None:
    """TV-3 (MP-6): `line_mismatch: ignore` passes a 19200-baud host's bytes unchanged."""
    host = connect(open_target, overrides={"knobs": {"line_mismatch": "ignore"}}, baudrate=19200)
    host.exchange(GET_POSITION, ZEROS + CR)


@pytest.mark.control
@pytest.mark.parametrize(
    ("settings", "overrides", "line"),
    [
        pytest.param(
            {"baudrate": 19200},
            None,
            "main: host uses 19200 8N1, device expects 9600 8N1; "
            "traffic will be garbled (line_mismatch=garble)",
            marks=pytest.mark.smoke,
        ),
        (
            {"stopbits": serial.STOPBITS_TWO},
            None,
            "main: host uses 9600 8N2, device expects 9600 8N1; "
            "only the stop bits differ, which corrupts nothing (line_mismatch=garble)",
        ),
        (
            {"baudrate": 19200},
            {"knobs": {"line_mismatch": "ignore"}},
            "main: host uses 19200 8N1, device expects 9600 8N1; "
            "traffic passes unchanged (line_mismatch=ignore)",
        ),
    ],
    ids=["19200", "8N2", "ignore"],
)
def test_tv_003_mismatch_is_logged_once(
    open_target: OpenTarget,
    log_of: LogOf,
    settings: dict[str, Any],
    overrides: dict[str, Any] | None,
    line: str,
) -> None:
    """TV-3 (MP-4, MP-5): one warning naming device, port, both settings and the knob in force, once
    a byte crosses the line; the traffic that follows logs nothing more."""
    host = connect(open_target, overrides=overrides, **settings)
    log = log_of(host, overrides)
    host.send(GET_POSITION)
    assert log.wait_line("host uses") == line
    host.send(GET_POSITION)
    host.port.timeout = 0.1
    host.port.read(13)  # the reply, or nothing on a garbled line: only the log matters here
    assert not [entry for entry in log.drain() if "host uses" in entry]


@pytest.mark.smoke
@pytest.mark.parametrize("frame", ["63 0D", "7A 63 0D"])
def test_tv_004_parity_host_gets_a_frame_error(
    open_target: OpenTarget, request: pytest.FixtureRequest, frame: str
) -> None:
    """TV-4 (MP-6, MP-24): an 8E1 host's `63` reaches the device with a framing error (its parity
    bit, 0, sits in the stop position) and its CR clean, so the device answers `31 0D`, which that
    host decodes as `00` (framing error) and `C3` (parity error). After the unknown `7A` the '1'
    replaces the pending '4'."""
    if not carries_parity(request.config):
        pytest.skip(NO_PARITY)  # a PTY host at 8E1 would be seen as 8N1 (MP-4)
    host = connect(open_target, parity=serial.PARITY_EVEN)
    host.exchange(hx(frame), hx("00 C3"))


def usb_host(open_target: OpenTarget, rtscts: bool) -> Host:
    """An `mp285a` host; on a daemon device time runs 10× (`Host.after` scales the instants)."""
    return connect(open_target, "mp285a", scale=10, rtscts=rtscts)


def start_tv05_move(host: Host) -> float:
    """`56 C8 00 0D`, then the TV-31 move; the instant the device had its frame."""
    host.exchange(hx("56 C8 00 0D"), CR)
    return host.send(LONG_X)


def interrupt_at_one_second(host: Host, moved: float, frame: bytes) -> None:
    """Write `frame` so that its first byte (the ^C) is the device's 1.000 s into the move."""
    host.quiet_until(host.after(moved, 1.0 - CHAR))
    host.send(frame)


@pytest.mark.control
@pytest.mark.parametrize(
    ("interrupt", "tail"), [("03 63 0D", "30 0D"), ("03", "")], ids=["ctrl-c-and-query", "ctrl-c"]
)
def test_tv_005_usb_without_rtscts_loses_bytes_while_busy(
    open_target: OpenTarget, log_of: LogOf, interrupt: str, tail: str
) -> None:
    """TV-5 (MP-7, MP-2, MP-5): a USB host without RTS/CTS interrupts the move at 1.000 s with
    `03 63 0D`: `3D` at once (the ^C is the kept byte), `63 0D` are lost, the move's `0D` at
    1.150 s, then `30 0D` right behind it. A lone ^C works normally. The device is idle again
    afterwards, and its warning says bytes sent while it is busy are lost."""
    host = usb_host(open_target, rtscts=False)
    log = log_of(host, profile="mp285a")
    moved = start_tv05_move(host)
    interrupt_at_one_second(host, moved, hx(interrupt))
    host.expect_at(hx("3D"), host.after(moved, 1.0 + CHAR))
    host.expect_at(CR, host.after(moved, 1.15 + CHAR))
    if tail:
        host.expect_at(hx(tail), host.after(moved, 1.15 + 3 * CHAR))
    assert len(host.position()) == 13
    host.quiet(0.1)
    assert "bytes sent while the device is busy are lost" in log.wait_line("host uses")


@pytest.mark.control
def test_tv_005_with_rtscts_nothing_is_lost(open_target: OpenTarget) -> None:
    """TV-5 (MP-7): with RTS/CTS the same bytes behave as TV-32: `3D` at 1.000 s, the halted position
    as the CR arrives, `0D` at 1.150 s."""
    host = usb_host(open_target, rtscts=True)
    moved = start_tv05_move(host)
    interrupt_at_one_second(host, moved, hx("03 63 0D"))
    host.expect_at(hx("3D"), host.after(moved, 1.0 + CHAR))
    data = host.read(13)
    host.assert_at(host.now(), host.after(moved, 1.0 + 15 * CHAR))
    x = int.from_bytes(data[:4], "little", signed=True)
    if host.target.virtual:
        assert x == 5000, show(data)  # 1.000 s at 5000 µsteps/s
    else:
        assert 0 < x < 25_000, show(data)  # where the host's timing let the ^C find it
    assert data[4:] == ZEROS[4:] + CR, show(data)
    host.expect_at(CR, host.after(moved, 1.15 + CHAR))
