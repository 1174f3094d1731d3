"""Host line settings read through the PTY master (emulator/hosting/transports/pty.py), including the
arbitrary rates a host sets with BOTHER and TCSETS2."""

from __future__ import annotations

import fcntl
import os
import struct
import termios
from collections.abc import Iterator

import pytest

from emulator.hosting.transports.pty import BOTHER, CBAUD, TCGETS2, host_settings

TCSETS2 = 0x402C542B
#: struct termios2: four tcflag_t, c_line, 19 control characters, then c_ispeed and c_ospeed
CFLAG_OFFSET, ISPEED_OFFSET, OSPEED_OFFSET = 8, 36, 40


@pytest.fixture
def pty_pair() -> Iterator[tuple[int, int]]:
    master, slave = os.openpty()
    yield master, slave
    os.close(slave)
    os.close(master)


def set_other_rate(slave: int, baud: int) -> None:
    raw = bytearray(fcntl.ioctl(slave, TCGETS2, bytes(44)))
    cflag = struct.unpack_from("I", raw, CFLAG_OFFSET)[0]
    struct.pack_into("I", raw, CFLAG_OFFSET, (cflag & ~CBAUD) | BOTHER)
    struct.pack_into("II", raw, ISPEED_OFFSET, baud, baud)
    fcntl.ioctl(slave, TCSETS2, bytes(raw))


def test_standard_rate_and_stop_bits(pty_pair: tuple[int, int]) -> None:
    master, slave = pty_pair
    attrs = termios.tcgetattr(slave)
    attrs[2] |= termios.CSTOPB | termios.CRTSCTS
    attrs[4] = attrs[5] = termios.B19200
    termios.tcsetattr(slave, termios.TCSANOW, attrs)
    settings = host_settings(master)
    assert (settings.baud, settings.stop_bits, settings.rtscts) == (19200, 2, True)


def test_arbitrary_rate_through_bother(pty_pair: tuple[int, int]) -> None:
    master, slave = pty_pair
    set_other_rate(slave, 14400)
    assert host_settings(master).baud == 14400


def test_zero_rate_is_unknown_not_a_division_by_zero(pty_pair: tuple[int, int]) -> None:
    master, slave = pty_pair
    set_other_rate(slave, 0)
    assert host_settings(master).baud is None
