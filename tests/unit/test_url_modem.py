"""Modem lines on the `stageemu://` URL (emulator/urlhandler/lines.py, emulator/hosting/transports/modem.py):
each family's declared lines, the MP-285A's RTS/CTS flow control in both directions, and a host
whose UART waits for a CTS the MS2000 never asserts. Virtual time unless a test says otherwise, so
every wait is exact and costs no wall time."""

from __future__ import annotations

import logging

import pytest
import serial

import emulator.urlhandler  # noqa: F401  (registers stageemu://)
from emulator.hosting.port import INPUT_BACKLOG
from emulator.hosting.transports.inprocess import RECEIVE_BUFFER
from tests.conformance.mp285.wire import DUMP_B
from tests.unit.conftest import OpenUrl

VERSION = b":A Version: USB-9.2k \r\n"


def lines(port: serial.SerialBase) -> tuple[bool, bool, bool, bool]:
    return port.cts, port.dsr, port.cd, port.ri


@pytest.mark.parametrize(
    ("profile", "expected"),
    [
        ("mp285", (False, False, False, False)),  # MP-1: three wires
        ("mp285a", (True, False, False, False)),  # MP-2: CTS is flow control, room for input now
        ("ms2000", (False, False, False, False)),  # MS-1: never asserted
    ],
)
def test_each_family_declares_its_lines(open_url: OpenUrl, profile: str, expected: tuple[bool, ...]) -> None:
    port = open_url(f"stageemu://{profile}?time=virtual", rtscts=profile == "mp285a")
    assert lines(port) == expected


def test_rts_dtr_and_break_do_not_reach_a_device_without_flow_control(
    open_url: OpenUrl, caplog: pytest.LogCaptureFixture
) -> None:
    port = open_url("stageemu://ms2000?time=virtual")
    with caplog.at_level(logging.INFO, logger="stage_emu.modem"):
        port.rts = False
        port.dtr = False
        port.send_break(0.01)
    assert port.read_until(b"\r\n") == b""  # nothing came of them
    port.write(b"V\r")
    assert port.read_until(b"\r\n") == VERSION
    assert "host set RTS off (ignored: the device has no flow control)" in caplog.text
    assert "host set DTR off (ignored: the device has no DTR input)" in caplog.text


def test_rts_off_holds_the_mp285a_output_until_it_is_on(
    open_url: OpenUrl, caplog: pytest.LogCaptureFixture
) -> None:
    port = open_url("stageemu://mp285a?time=virtual", rtscts=True)
    with caplog.at_level(logging.INFO, logger="stage_emu.modem"):
        port.rts = False
        port.write(b"s\r")
        start = port.device_time
        assert port.read(33) == b""
        assert port.device_time == pytest.approx(start + 1.0, abs=1e-9)  # the whole timeout passed
        assert port.in_waiting == 0
        port.rts = True
    assert port.in_waiting == 33  # held, not lost: there at once
    assert port.read(33) == DUMP_B
    assert "RTS off: the device holds its output" in caplog.text
    assert "RTS on: the device sends again (33 bytes held meanwhile)" in caplog.text


def test_rts_set_before_opening_applies_at_open(open_url: OpenUrl) -> None:
    port = open_url("stageemu://mp285a?time=virtual", rtscts=True, do_not_open=True)
    port.rts = False
    port.open()
    port.write(b"c\r")
    assert port.read(13) == b""
    port.rts = True
    assert port.read(13) == bytes(12) + b"\r"


def test_output_held_by_rts_is_bounded_like_the_receive_buffer(
    open_url: OpenUrl, caplog: pytest.LogCaptureFixture
) -> None:
    port = open_url("stageemu://mp285a?time=virtual&timing=fast", rtscts=True)
    port.rts = False
    replies = RECEIVE_BUFFER // len(DUMP_B) + 4  # more status dumps than the buffer holds
    with caplog.at_level(logging.WARNING):
        port.write(b"s\r" * replies)
        port.advance(1.0)
    stats = port.control.list()[0]["ports"][0]["stats"]
    assert stats["output_dropped"] == replies * len(DUMP_B) - RECEIVE_BUFFER
    port.rts = True
    assert port.in_waiting == RECEIVE_BUFFER
    assert port.read(RECEIVE_BUFFER) == (DUMP_B * replies)[:RECEIVE_BUFFER]  # the oldest kept
    assert "held while the host's RTS is off fills the port's buffer" in caplog.text


def test_mp285a_cts_is_off_while_its_input_is_full(open_url: OpenUrl) -> None:
    port = open_url("stageemu://mp285a?time=virtual", rtscts=True, write_timeout=0)
    taken = port.write(bytes(INPUT_BACKLOG + 100))  # NULs: bytes the device discards (MP-21)
    assert taken == INPUT_BACKLOG
    assert port.cts is False
    port.timeout = 2 * 10 / 9600  # two character times pass: two bytes leave the backlog
    port.read(1)
    assert port.cts is True


def test_a_host_with_rtscts_cannot_send_to_a_device_that_never_asserts_cts(
    open_url: OpenUrl, caplog: pytest.LogCaptureFixture
) -> None:
    port = open_url("stageemu://ms2000?time=virtual", rtscts=True)
    with caplog.at_level(logging.INFO, logger="stage_emu.modem"):
        assert port.write(b"V\r") == 2  # into its transmit buffer, as a driver takes it
        assert port.read_until(b"\r\n") == b""
        assert port.out_waiting == 2
        port.rtscts = False
    assert port.read_until(b"\r\n") == VERSION
    assert port.out_waiting == 0
    assert "the device does not assert CTS: its bytes wait" in caplog.text
    assert "2 bytes the host held back for CTS go to the device" in caplog.text


def test_a_full_transmit_buffer_blocks_the_write_until_its_timeout(open_url: OpenUrl) -> None:
    port = open_url("stageemu://ms2000?time=virtual", rtscts=True, write_timeout=0.5)
    start = port.device_time
    with pytest.raises(serial.SerialTimeoutException):
        port.write(b"V\r" * INPUT_BACKLOG)
    assert port.device_time == pytest.approx(start + 0.5, abs=1e-9)
    assert port.out_waiting == INPUT_BACKLOG


def test_flushing_the_output_drops_the_bytes_held_for_cts(open_url: OpenUrl) -> None:
    port = open_url("stageemu://ms2000?time=virtual", rtscts=True)
    port.write(b"V\r")
    port.reset_output_buffer()
    assert port.out_waiting == 0
    port.rtscts = False
    assert port.read_until(b"\r\n") == b""
    port.write(b"V\r")
    assert port.read_until(b"\r\n") == VERSION


def test_rts_holds_output_in_real_time_too(open_url: OpenUrl) -> None:
    port = open_url("stageemu://mp285a?timing=fast", rtscts=True, timeout=0.2)
    port.rts = False
    port.write(b"c\r")
    assert port.read(13) == b""
    port.rts = True
    assert port.read(13) == bytes(12) + b"\r"
