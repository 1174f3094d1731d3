"""Virtual time on in-process ports (`stageemu://PROFILE?time=virtual`, emulator/urlhandler): device
time passes only while the host waits, at once, to the next thing due; every instant is exact."""

from __future__ import annotations

import threading

import pytest
import serial

import emulator.urlhandler  # noqa: F401  (registers stageemu://)
from emulator.control_client import ControlFailure
from emulator.urlhandler.hosted import serve
from emulator.urlhandler.url import VIRTUAL, AttachOptions, UrlOptions, parse_url
from emulator.wire_time import char_time
from protocols.clients.ms2000 import MS2000

CHAR = char_time(9600)


def open_virtual(profile: str = "ms2000", **settings: object) -> serial.SerialBase:
    settings = {"baudrate": 9600, "timeout": 1, **settings}
    return serial.serial_for_url(f"stageemu://{profile}?time=virtual", **settings)


def test_a_reply_arrives_at_its_exact_instant() -> None:
    """`W X\\r` is 4 characters in, `:A 0\\r\\n` 6 out (MS-1 pacing at 9600 8N1): the reply's last
    byte is in at exactly 10 character times, whatever the machine is doing."""
    with open_virtual() as port:
        start = port.device_time
        port.write(b"W X\r")
        assert port.read(6) == b":A 0\r\n"
        assert port.device_time - start == pytest.approx(10 * CHAR, abs=1e-9)


def test_a_read_that_gets_nothing_lets_exactly_its_timeout_pass() -> None:
    with open_virtual() as port:
        start = port.device_time
        assert port.read(1) == b""
        assert port.device_time - start == pytest.approx(1.0, abs=1e-9)


def test_a_ten_second_move_passes_as_the_host_polls() -> None:
    """The move ends when the motion model says (TV-style poll until N), with no wall-clock wait."""
    with open_virtual() as port:
        port.write(b"S X=0.1\r")
        assert port.read(4) == b":A\r\n"
        port.write(b"M X=10000\r")  # 1 mm at 0.1 mm/s
        assert port.read(4) == b":A\r\n"
        moved = port.device_time
        while True:
            port.write(b"/\r")
            answer = port.read(3)
            if answer == b"N\r\n":
                break
            assert answer == b"B\r\n"
            assert port.read(1) == b""  # the host waits 1 s between polls: device time passes
        assert 10.0 <= port.device_time - moved <= 11.5
        port.write(b"W X\r")
        assert port.read(10) == b":A 10000\r\n"


def test_advance_and_control_step_move_device_time() -> None:
    with open_virtual() as port:
        start = port.device_time
        port.advance(2.5)
        assert port.device_time == pytest.approx(start + 2.5)
        port.control.step(1.0)
        assert port.device_time == pytest.approx(start + 3.5)


def test_advance_needs_virtual_time() -> None:
    with (
        serial.serial_for_url("stageemu://ms2000?timing=fast", baudrate=9600, timeout=1) as port,
        pytest.raises(serial.SerialException, match="advance needs virtual time"),
    ):
        port.advance(1.0)


def test_events_wait_in_device_time() -> None:
    """The in-process control channel's events come as the device makes them: a 1 s move's
    completion is pushed when device time reaches it, while `events` waits."""
    with open_virtual() as port:
        control = port.control
        control.subscribe("ms2000")
        port.write(b"M X=1000\r")
        assert port.read(4) == b":A\r\n"
        events = [event["ev"] for event in control.events(timeout=5)]
        assert "move_complete" in events
        assert control.get("ms2000", "busy") is False


def test_a_reader_thread_waits_for_a_writer_when_nothing_is_due() -> None:
    """With nothing scheduled, a read without timeout waits for another thread of the host."""
    with open_virtual(timeout=None) as port:
        got: list[bytes] = []
        reader = threading.Thread(target=lambda: got.append(port.read(6)))
        reader.start()
        port.write(b"W X\r")
        reader.join(10)
        assert not reader.is_alive() and got == [b":A 0\r\n"]


def test_a_served_device_outlives_its_ports() -> None:
    """`serve` makes a device a harness owns: ports open and close on it like a daemon's PTY, its
    state stays, its other channels open by URL too."""
    device = serve(UrlOptions(profile="ms2000-ttlrep", time=VIRTUAL))  # at 115200 (its DIP switches)
    try:
        with serial.serial_for_url(device.url(), baudrate=115200, timeout=1) as port:
            port.write(b"M X=100\r")
            assert port.read(4) == b":A\r\n"
            with serial.serial_for_url(device.url("aux"), baudrate=115200, timeout=0.1) as aux:
                assert aux.read(1) == b""
        assert device.now() > 0
        with serial.serial_for_url(device.url(), baudrate=115200, timeout=3) as port:
            port.read(1)  # let the move end
            port.write(b"W X\r")
            assert port.read(8) == b":A 100\r\n"
    finally:
        device.close()
    with pytest.raises(ValueError, match=r"no device .* is served"):
        serial.serial_for_url(device.url(), baudrate=9600)


def test_a_traffic_subscription_needs_a_daemon() -> None:
    with open_virtual() as port, pytest.raises(ControlFailure, match="need a daemon"):
        port.control.subscribe("ms2000", traffic=True)


@pytest.mark.parametrize(
    ("url", "message"),
    [
        ("stageemu://ms2000?time=virtual&scale=10", "scale has no meaning in virtual time"),
        ("stageemu://ms2000?time=later", "time must be real or virtual"),
        ("stageemu://ms2000?attach=x", "attach= takes only channel= beside it"),
        ("stageemu://?attach=", "attach= and channel= need a name"),
        ("stageemu://ms2000?channel=aux", "channel= goes with attach="),
    ],
)
def test_bad_virtual_time_urls_are_one_line(url: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        parse_url(url)


def test_an_attach_url_names_the_device_and_channel() -> None:
    assert parse_url("stageemu://?attach=ms2000-3&channel=aux") == AttachOptions("ms2000-3", "aux")


def test_the_bundled_client_pauses_in_device_time() -> None:
    """`wait_until_idle` pauses with the sleep and clock it is given: in virtual time the port's,
    so its pauses pass device time (with `time.sleep` they would pass none, and cost wall time)."""
    with open_virtual() as port:
        stage = MS2000(port)
        stage.move(X=100000)  # 10 mm at the default speed
        start = port.device_time
        stage.wait_until_idle(timeout=60, poll=0.05, sleep=port.advance, clock=lambda: port.device_time)
        assert stage.where()["X"] == 100000.0
        assert 1.0 < port.device_time - start < 5.0
