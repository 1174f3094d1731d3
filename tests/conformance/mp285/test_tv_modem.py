"""TV-50 ... TV-53: modem lines (MP-1, MP-2, MP-7). The RS-232 port has three wires, so no line is
asserted and RTS and DTR go nowhere; on the MP-285A's USB port CTS is the device's flow control (on
while it can take input), DSR, CD and RI are not asserted (inferred), and the host's RTS holds the
device's output. A host that enables RTS/CTS on the three-wire port waits for a CTS that never comes,
as with a real UART (the emulator's choice where MP-1 says nothing of the host's side). Marked
`modem`: they skip where the lines do not reach the test (a pseudo-terminal, raw TCP, a real port
given as a device path)."""

from __future__ import annotations

import pytest
import serial

from tests.conformance.mp285.wire import (
    CR,
    DUMP_B,
    GET_POSITION,
    GET_STATUS,
    ZEROS,
    OpenTarget,
    connect,
    show,
)

pytestmark = pytest.mark.modem


def lines(port: serial.SerialBase) -> tuple[bool, bool, bool, bool]:
    return port.cts, port.dsr, port.cd, port.ri


def test_tv_050_rs232_asserts_no_line_and_ignores_rts_and_dtr(open_target: OpenTarget) -> None:
    """TV-50 (MP-1): on `mp285` CTS, DSR, CD and RI read off; with RTS and DTR off `63 0D` → the 13
    position bytes as usual."""
    host = connect(open_target)
    assert lines(host.port) == (False, False, False, False)
    host.port.rts = False
    host.port.dtr = False
    host.exchange(GET_POSITION, ZEROS + CR)


def test_tv_051_usb_asserts_cts_only(open_target: OpenTarget) -> None:
    """TV-51 (MP-2, MP-7): on `mp285a`, a host with RTS/CTS reads CTS on (the device can take input)
    and DSR, CD and RI off (inferred: the quick reference names RTS/CTS alone)."""
    host = connect(open_target, "mp285a")
    assert lines(host.port) == (True, False, False, False)


def test_tv_052_usb_rts_off_holds_the_reply(open_target: OpenTarget) -> None:
    """TV-52 (MP-2, MP-7): on `mp285a` with RTS off, `73 0D` → nothing for 1 s; RTS on → dump B, all
    33 bytes (held, not lost); `63 0D` then → the 13 position bytes as usual."""
    host = connect(open_target, "mp285a")
    host.port.rts = False
    host.send(GET_STATUS)
    host.quiet(1.0)
    host.port.rts = True
    assert show(host.read(33)) == show(DUMP_B)
    host.exchange(GET_POSITION, ZEROS + CR)


def test_tv_053_rs232_host_with_rtscts_cannot_send(open_target: OpenTarget) -> None:
    """TV-53 (MP-1; the host's side is a choice): a host that enables RTS/CTS on `mp285` writes
    `63 0D` → nothing for 1 s (its UART waits for CTS); once it turns RTS/CTS off its held bytes
    go out → the 13 position bytes."""
    host = connect(open_target, rtscts=True)
    host.send(GET_POSITION)
    host.quiet(1.0)
    host.port.rtscts = False
    assert show(host.read(13)) == show(ZEROS + CR)
