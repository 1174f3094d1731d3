"""Modem lines (§1, MS-1): TV-221…TV-224. The controller asserts none of CTS, DSR, CD and RI on
either port and ignores RTS and DTR; a host that enables RTS/CTS flow control against it therefore
waits for a CTS that never comes, as with a real UART (the emulator's choice where MS-1 is silent
about the host's side). Marked `modem`: they skip where the lines do not reach the test (a
pseudo-terminal, raw TCP, a real port given as a device path)."""

from __future__ import annotations

from collections.abc import Callable

import pytest
import serial

from tests.conformance.ms2000.conftest import VERSION, Host

pytestmark = pytest.mark.modem

TTLREP = "ms2000-ttlrep"


def lines(port: serial.SerialBase) -> tuple[bool, bool, bool, bool]:
    return port.cts, port.dsr, port.cd, port.ri


def test_tv_221_no_line_is_asserted(ms: Host) -> None:
    """TV-221 (MS-1): CTS, DSR, CD and RI all read off on the main port."""
    assert lines(ms.port) == (False, False, False, False)


def test_tv_222_rts_and_dtr_are_ignored(ms: Host) -> None:
    """TV-222 (MS-1): with RTS and DTR off `V\\r` ⇒ the version line as usual; on again, the same."""
    ms.port.rts = False
    ms.port.dtr = False
    ms.ask(b"V\r", VERSION)
    ms.port.rts = True
    ms.port.dtr = True
    ms.ask(b"V\r", VERSION)
    assert lines(ms.port) == (False, False, False, False)


def test_tv_223_a_host_with_rtscts_cannot_send(ms: Host) -> None:
    """TV-223 (MS-1; the host's side is a choice): a host with RTS/CTS flow control writes `V\\r` ⇒
    nothing within 1 s (its UART waits for CTS); once it turns RTS/CTS off its held bytes go out ⇒
    the version line."""
    ms.port.rtscts = True  # after `connect`, which may have to bring a real controller to P0
    ms.write(b"V\r")
    ms.silent()
    ms.port.rtscts = False
    ms.expect(VERSION)


def test_tv_224_the_aux_port_asserts_nothing(connect: Callable[..., Host]) -> None:
    """TV-224 (MS-1, MS-TTLREP-1): the TTL REPORT's auxiliary port asserts no line either."""
    ms = connect(TTLREP)
    assert lines(ms.target.open_aux()) == (False, False, False, False)
