"""Modem lines over a daemon's RFC 2217 port, driven by pyserial's own `rfc2217://` client: the
MP-285A's CTS and its output held by the client's RTS (MP-2, MP-7), the MS2000's lines (MS-1) and a
client with RTS/CTS that cannot send to it until it turns RTS/CTS off. The daemon says so in its log.
"""

from __future__ import annotations

from pathlib import Path

import serial

from tests.support.daemon import start_daemon

#: how long a read waits for bytes that are due (they come in milliseconds; this only bounds a hang)
HANG_S = 10.0
#: how long a read must get nothing where the device's bytes are held
QUIET_S = 0.5
DUMP_B = bytes.fromhex(
    "62 03 01 01 04 00 14 00 63 00 05 00 88 13 01 78 C4 09 88 13 50 00 00 00 19 00 04 00 DC 05 2E 01 0D"
)
VERSION = b":A Version: USB-9.2k \r\n"


def test_the_client_rts_holds_the_mp285a_output(tmp_path: Path) -> None:
    daemon = start_daemon(tmp_path, ["-v", "--profile", "mp285a", "--rfc2217", "127.0.0.1:0"], expect_ports=1)
    try:
        url = daemon.port("mp285a")
        with serial.serial_for_url(url, baudrate=9600, rtscts=True, timeout=QUIET_S) as port:
            assert (port.cts, port.dsr, port.cd, port.ri) == (True, False, False, False)
            port.rts = False
            port.write(b"s\r")
            assert port.read(33) == b""
            port.timeout = HANG_S
            port.rts = True
            assert port.read(33) == DUMP_B
        said = daemon.log.wait_line("host set RTS off: the device holds its output", 0, HANG_S)
        assert said is not None, daemon.stderr()
        assert daemon.log.wait_line("(33 bytes held meanwhile)", said[0], HANG_S) is not None, daemon.stderr()
    finally:
        daemon.stop()


def test_a_client_with_rtscts_waits_for_the_ms2000_cts(tmp_path: Path) -> None:
    daemon = start_daemon(tmp_path, ["-v", "--profile", "ms2000", "--rfc2217", "127.0.0.1:0"], expect_ports=1)
    try:
        with serial.serial_for_url(daemon.port("ms2000"), baudrate=9600, timeout=QUIET_S) as port:
            assert (port.cts, port.dsr, port.cd, port.ri) == (False, False, False, False)
            port.rts = False
            port.dtr = False
            port.write(b"V\r")
            port.timeout = HANG_S
            assert port.read_until(b"\r\n") == VERSION  # RTS and DTR go nowhere
            port.timeout = QUIET_S
            port.rtscts = True
            port.write(b"V\r")
            assert port.read_until(b"\r\n") == b""
            port.timeout = HANG_S
            port.rtscts = False
            assert port.read_until(b"\r\n") == VERSION
        assert daemon.log.wait_line("the device does not assert CTS", 0, HANG_S) is not None, daemon.stderr()
    finally:
        daemon.stop()
