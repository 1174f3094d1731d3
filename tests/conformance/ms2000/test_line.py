"""Line settings: stop bits, DIP-switch baud rates and hosts at other settings (§1): TV-116…TV-121."""

from __future__ import annotations

from collections.abc import Callable

import pytest
import serial

from tests.conformance.conftest import NO_PARITY, carries_parity
from tests.conformance.ms2000.conftest import ACK, SILENT, VERSION, Host


@pytest.mark.smoke
def test_tv_116_stop_bits(ms: Host) -> None:
    """TV-116 (MS-3, MS-4): `SB X=2` takes effect at once; a host still sending 1 stop bit is
    understood (a UART samples only the first stop bit)."""
    ms.run([(b"SB X?\r", b":A X=1\r\n"), (b"SB X=3\r", b":N-4\r\n"), (b"SB X=2\r", ACK), (b"V\r", VERSION)])


@pytest.mark.control
def test_tv_117_dip_baud_read_at_power_up(ms: Host) -> None:
    """TV-117 (MS-2, MS-4): SW4 and SW5 down select 115200 at the next power-up; a host at 115200
    is understood, one at 9600 gets nothing back."""
    ms.input("dip", sw4="down", sw5="down")
    ms.input("power_cycle")
    assert ms.get("baud") == 115200
    ms.input("host_line", baud=115200)
    ms.ask(b"V\r", VERSION)
    ms.input("host_line", baud=9600)
    ms.run([(b"V\r", b""), SILENT])


@pytest.mark.control
def test_tv_118_mixed_dip_baud_rates(ms: Host) -> None:
    """TV-118 (MS-2): SW4 down + SW5 up is 19200, SW4 up + SW5 down 28800; switches are read at
    power-up only."""
    ms.input("dip", sw4="down", sw5="up")
    ms.input("power_cycle")
    assert ms.get("baud") == 19200
    ms.input("dip", sw4="up", sw5="down")
    ms.port.baudrate = 19200
    ms.ask(b"V\r", VERSION)
    ms.input("power_cycle")
    assert ms.get("baud") == 28800


@pytest.mark.control
def test_tv_119_mismatch_ignored_by_knob(connect: Callable[..., Host]) -> None:
    """TV-119 (MS-4): with `line_mismatch: ignore` a host at another baud rate is understood."""
    host = connect(overrides={"knobs": {"line_mismatch": "ignore"}})
    host.input("host_line", baud=115200)
    host.ask(b"V\r", VERSION)


@pytest.mark.control
def test_tv_120_data_bits_and_parity(ms: Host) -> None:
    """TV-120 (MS-1, MS-4): a host at 7E1 (declared, a pseudo-terminal cannot show it) gets nothing;
    back at 8N1 it is understood."""
    ms.input("host_line", baud=9600, data_bits=7, parity="even")
    ms.run([(b"V\r", b""), SILENT])
    ms.input("host_line", baud=9600, data_bits=8, parity="none")
    ms.ask(b"V\r", VERSION)


@pytest.mark.smoke
def test_tv_120_data_bits_and_parity_on_the_wire(
    request: pytest.FixtureRequest, connect: Callable[..., Host]
) -> None:
    """TV-120 (MS-1, MS-4) with the host's own port at 7E1 instead of the control input, where the
    port carries data bits and parity (as TV-4 of the MP-285): the host gets nothing; back at 8N1
    it is understood."""
    if not carries_parity(request.config):
        pytest.skip(NO_PARITY)  # on the emulator's PTY test_tv_120_data_bits_and_parity declares them
    ms = connect()
    ms.port.bytesize, ms.port.parity = serial.SEVENBITS, serial.PARITY_EVEN
    ms.run([(b"V\r", b""), SILENT])
    ms.port.bytesize, ms.port.parity = serial.EIGHTBITS, serial.PARITY_NONE
    ms.ask(b"V\r", VERSION)


@pytest.mark.smoke
@pytest.mark.control
def test_tv_121_ports(ms: Host) -> None:
    """TV-121 (MS-5): the main port is a pseudo-terminal (in virtual time the in-process URL that
    stands for it); builds without TTL REPORT have no auxiliary port (the emulator lists only the
    ports a device has, so `aux` reads as absent)."""
    ports = ms.get("ports")
    assert ms.is_port_path(ports["main"])
    assert ports.get("aux") is None
