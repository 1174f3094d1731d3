"""A serial port's RTS and DTR carry the device's modem lines to the host through a null-modem cable
(the host reads them as CTS and as DSR and CD): emulator/hosting/transports/serial.py `_drive_modem_lines`."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from emulator.device import LineSettings, ModemLines
from emulator.hosting.transports.serial import SerialTransport

PLAIN = LineSettings(9600, 8, "none", 1, False, False)
RTSCTS = LineSettings(9600, 8, "none", 1, True, False)


@dataclass
class FakePort:
    """What pyserial's port offers for the lines: set as asserted, as pyserial opens a port."""

    rts: bool = True
    dtr: bool = True


@dataclass
class Sink:
    lines: ModemLines

    def modem_lines(self) -> ModemLines:
        return self.lines


def drive(line: LineSettings, lines: ModemLines) -> FakePort:
    transport = SerialTransport("/dev/ttyUSB0")
    port = FakePort()
    transport._sink, transport._port, transport._line = Sink(lines), port, line  # type: ignore[assignment]
    transport._drive_modem_lines()
    return port


def test_a_device_that_asserts_nothing_lowers_both_lines() -> None:
    # MS-1 (MS2000) and MP-1 (MP-285 RS-232, three wires): the host reads CTS, DSR and CD off
    assert drive(PLAIN, ModemLines()) == FakePort(rts=False, dtr=False)


@pytest.mark.parametrize(
    ("lines", "expected"),
    [
        (ModemLines(cts=True), (True, False)),
        (ModemLines(dsr=True), (False, True)),
        (ModemLines(cd=True), (False, True)),
    ],
)
def test_rts_carries_cts_and_dtr_carries_dsr_and_cd(lines: ModemLines, expected: tuple[bool, bool]) -> None:
    port = drive(PLAIN, lines)
    assert (port.rts, port.dtr) == expected


def test_with_rts_cts_the_driver_keeps_rts() -> None:
    # MP-2/MP-7 (MP-285A): the kernel drives RTS from its input buffer (the device holding the host
    # off); only DTR is set
    port = drive(RTSCTS, ModemLines(cts=True))
    assert port == FakePort(rts=True, dtr=False)


def test_a_port_without_modem_lines_is_left_as_it_is() -> None:
    class NoLines:
        @property
        def rts(self) -> bool:
            raise OSError(25, "Inappropriate ioctl for device")

        @rts.setter
        def rts(self, value: bool) -> None:
            raise OSError(25, "Inappropriate ioctl for device")

    transport = SerialTransport("/dev/pts/9")
    transport._sink, transport._port, transport._line = Sink(ModemLines()), NoLines(), PLAIN  # type: ignore[assignment]
    transport._drive_modem_lines()  # a pseudo-terminal: no error, nothing to drive
