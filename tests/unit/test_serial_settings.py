"""The serial transport's settings: a device's line settings as pyserial's, the settings a port did
not take, the one line for each port that cannot be served (missing, busy, not a serial port,
settings it refuses), the host described on a serial line, and serial ports in rig files and
`--profile`."""

from __future__ import annotations

import fcntl
import os
import termios
from collections.abc import Iterator
from pathlib import Path

import pytest
import serial

from emulator.device import HostLine, LineSettings
from emulator.hosting.line_errors import UNSEEN_HOST
from emulator.hosting.rig import load_rig, rig_from_profiles
from emulator.hosting.transports.pty import PortError
from emulator.hosting.transports.serial import SerialHost
from emulator.hosting.transports.serial_port import open_failure, open_port, port_settings, refused_settings
from emulator.profiles.profile import ProfileError
from tests.support.probe_device import PROBE_PROFILE as PROBE  # (registers the `probe` family)

LINE = LineSettings(9600, 8, "none", 1, False, False)


def test_device_settings_as_pyserial_settings() -> None:
    assert port_settings(LINE) == {
        "baudrate": 9600,
        "bytesize": 8,
        "parity": serial.PARITY_NONE,
        "stopbits": serial.STOPBITS_ONE,
        "rtscts": False,
        "xonxoff": False,
    }
    usb = LineSettings(19200, 7, "odd", 1.5, True, False)  # the MP-285A's VCP asks for RTS/CTS (MP-2)
    assert port_settings(usb) == {
        "baudrate": 19200,
        "bytesize": 7,
        "parity": serial.PARITY_ODD,
        "stopbits": serial.STOPBITS_ONE_POINT_FIVE,
        "rtscts": True,
        "xonxoff": False,
    }
    with pytest.raises(PortError, match="cannot be set to 9600 9N1"):
        port_settings(LineSettings(9600, 9, "none", 1, False, False))


def test_what_a_port_did_not_take() -> None:
    assert refused_settings(LINE, HostLine(9600, 8, "none", 1)) is None
    assert refused_settings(LINE, HostLine(9700, 8, "none", 1)) is None  # within a UART's 2 %
    assert refused_settings(LINE, HostLine(9900, 8, "none", 1)) == "9600 baud (it runs at 9900)"
    seven_even = LineSettings(9600, 7, "even", 1, False, False)
    assert refused_settings(seven_even, HostLine(9600, 8, "none", 1)) == (
        "7 data bits (it keeps 8), even parity (it keeps none)"
    )
    one_and_a_half = LineSettings(9600, 8, "none", 1.5, False, False)
    assert refused_settings(one_and_a_half, HostLine(9600, 8, "none", 2)) is None  # POSIX sends 2
    assert refused_settings(one_and_a_half, HostLine(9600, 8, "none", 1)) == "1.5 stop bits (it keeps 1)"


@pytest.fixture
def pty_slave() -> Iterator[str]:
    master, slave = os.openpty()
    try:
        yield os.ttyname(slave)
    finally:
        os.close(slave)
        os.close(master)


def refusal(device: str, line: LineSettings = LINE) -> str:
    with pytest.raises(PortError) as info:
        open_port(device, line, 0.1)
    message = str(info.value)
    assert "\n" not in message
    return message


def test_a_missing_device(tmp_path: Path) -> None:
    assert refusal(str(tmp_path / "ttyUSB9")) == (
        f"serial port {tmp_path / 'ttyUSB9'}: no such device (is the adapter plugged in? "
        "`ls /dev/serial/by-id` lists them)"
    )


def test_a_busy_device(pty_slave: str) -> None:
    """Opened exclusively: a second opener (another program, a second daemon) is refused."""
    first = open_port(pty_slave, LINE, 0.1)
    try:
        assert (
            refusal(pty_slave)
            == f"serial port {pty_slave}: in use by another program (it is opened exclusively)"
        )
    finally:
        first.close()
    open_port(pty_slave, LINE, 0.1).close()  # free again


def test_a_device_locked_by_another_program(pty_slave: str) -> None:
    fd = os.open(pty_slave, os.O_RDWR | os.O_NOCTTY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        assert "in use by another program" in refusal(pty_slave)
    finally:
        os.close(fd)


def test_not_a_serial_port(tmp_path: Path) -> None:
    regular = tmp_path / "notes.txt"
    regular.write_text("mine\n")
    assert refusal(str(regular)) == f"serial port {regular}: not a serial port (it is a regular file)"
    assert regular.read_text() == "mine\n"
    assert refusal(str(tmp_path)) == f"serial port {tmp_path}: not a serial port (it is a directory)"
    assert refusal("/dev/null") == (
        "serial port /dev/null: not a serial port (the system refuses terminal settings on it)"
    )


def test_settings_the_port_refuses(pty_slave: str) -> None:
    """A driver that fails on the settings (emulator/hosting/transports/serial.py also reads back what a
    port took: tests/unit/test_serial_transport.py)."""
    seven_even = LineSettings(9600, 7, "even", 1, False, False)
    refused = termios.error(22, "Invalid argument")
    assert open_failure(pty_slave, seven_even, refused) == (
        f"serial port {pty_slave}: does not support 9600 7E1 (Invalid argument)"
    )
    assert open_failure(pty_slave, LINE, ValueError("Invalid baud rate: -1")) == (
        f"serial port {pty_slave}: does not support 9600 8N1 (Invalid baud rate: -1)"
    )


def test_the_host_on_a_serial_line_is_not_seen() -> None:
    host = SerialHost()
    assert host.describe() == UNSEEN_HOST
    assert host.filled(LINE) == LINE  # the model assumes the host matches
    assert "a host at other settings gets garbage from the UART" in UNSEEN_HOST


# ---- rig files and --profile ---------------------------------------------------------------------


def rig_error(tmp_path: Path, ports: str) -> str:
    rig = tmp_path / "rig.yaml"
    rig.write_text(f"spec: 1\ndevices:\n  - {{name: a, profile: {PROBE}, ports: [{ports}]}}\n")
    with pytest.raises(ProfileError) as info:
        load_rig(rig)
    return str(info.value).replace(str(rig), "rig.yaml")


def test_a_serial_port_in_a_rig(tmp_path: Path) -> None:
    rig = tmp_path / "rig.yaml"
    ports = "[{transport: serial, device: COM7}]"
    rig.write_text(f"spec: 1\ndevices:\n  - {{name: a, profile: {PROBE}, ports: {ports}}}\n")
    port = load_rig(rig).devices[0].ports[0]
    assert (port.transport, port.device, port.link) == ("serial", "COM7", None)


@pytest.mark.parametrize(
    ("ports", "message"),
    [
        (
            "{transport: serial}",
            "device: a serial port needs the device to open (/dev/ttyUSB0, COM7, a pyserial URL)",
        ),
        (
            "{transport: serial, device: COM7, link: x}",
            "devices[0].ports[0].link: does not apply to a serial port",
        ),
        (
            "{transport: serial, device: COM7, port: 7000}",
            "devices[0].ports[0].port: does not apply to a serial port",
        ),
        (
            "{transport: serial, device: COM7, bind: 0.0.0.0}",
            "devices[0].ports[0].bind: does not apply to a serial port",
        ),
        ("{transport: pty, device: COM7}", "devices[0].ports[0].device: does not apply to a pty port"),
        (
            "{transport: tcp, port: 7000, device: COM7}",
            "devices[0].ports[0].device: does not apply to a tcp port",
        ),
    ],
)
def test_bad_serial_port_entries_are_one_line(tmp_path: Path, ports: str, message: str) -> None:
    error = rig_error(tmp_path, ports)
    assert error.count("\n") == 0 and error.startswith("rig.yaml:3: ") and error.endswith(message), error


def test_one_serial_device_for_two_ports_is_refused(tmp_path: Path) -> None:
    rig = tmp_path / "rig.yaml"
    rig.write_text(
        "spec: 1\ndevices:\n"
        f"  - {{name: a, profile: {PROBE}, ports: [{{transport: serial, device: /dev/ttyUSB0}}]}}\n"
        f"  - {{name: b, profile: {PROBE}, ports: [{{transport: serial, device: /dev/ttyUSB0}}]}}\n"
    )
    with pytest.raises(ProfileError, match="serial device /dev/ttyUSB0 is used by two ports"):
        load_rig(rig)


def test_serial_option_serves_the_profile_on_the_device() -> None:
    rig = rig_from_profiles([PROBE], ("serial", "/dev/ttyUSB0"))
    port = rig.devices[0].ports[0]
    assert (port.channel, port.transport, port.device) == ("main", "serial", "/dev/ttyUSB0")
    with pytest.raises(ProfileError, match="--serial serves one --profile"):
        rig_from_profiles([PROBE, PROBE], ("serial", "/dev/ttyUSB0"))
    with pytest.raises(ProfileError, match="a link does not apply to a serial port"):
        rig_from_profiles([f"{PROBE}:/tmp/x"], ("serial", "/dev/ttyUSB0"))
