"""The MS-2000 model hosted by the real DeviceRunner on a manual clock: realistic byte-by-byte
input, paced output, a host at the wrong baud rate, and a second line arriving while the model is
still inside a move (device contract, MS-4, MS-13)."""

from __future__ import annotations

import logging

import pytest

from emulator.device import DeviceServices, LineSettings
from emulator.devices.ms2000.model import Ms2000Device
from emulator.hosting.clock import ManualClock
from emulator.hosting.runner import DeviceRunner
from emulator.profiles.profile import load_profile
from emulator.wire_time import REALISTIC, char_time
from tests.support.memory_transport import MemoryTransport

CHAR = char_time(9600)


def hosted(timing: str = REALISTIC) -> tuple[MemoryTransport, ManualClock]:
    """A runner with the model on a memory port (the port's sink keeps the runner alive)."""
    clock = ManualClock()
    profile = load_profile("ms2000")
    runner = DeviceRunner(lambda now: Ms2000Device("dut", profile, now, DeviceServices(None)), clock)
    port = MemoryTransport()
    runner.attach_transport("main", port, timing)
    port.attach(LineSettings(baud=9600, stop_bits=1))
    return port, clock


def test_realistic_round_trip_takes_wire_time() -> None:
    port, clock = hosted()
    port.send(b"V\r")
    clock.advance(2 * CHAR)
    assert port.take() == b""
    reply = b":A Version: USB-9.2k \r\n"
    clock.advance(len(reply) * CHAR + 1e-6)
    assert port.take() == reply


def test_wrong_host_baud_garbles_and_is_reported(caplog: pytest.LogCaptureFixture) -> None:
    """The mismatch is reported once bytes cross the line at it, not when the host merely sets it."""
    port, clock = hosted()
    with caplog.at_level(logging.WARNING):
        port.sink.host_line(LineSettings(baud=19200, stop_bits=1))  # type: ignore[union-attr]
        assert "garbled" not in caplog.text
        port.send(b"V\r")
        assert "garbled (line_mismatch=garble)" in caplog.text
    clock.advance(1.0)
    assert port.take() == b""


def test_move_then_status_polling_through_runner() -> None:
    port, clock = hosted("fast")
    port.send(b"M X=10000\r/\r")
    assert port.take() == b":A\r\nB\r\n"
    clock.advance(1.0)
    port.send(b"/\rW X\r")
    assert port.take() == b"N\r\n:A 10000\r\n"
