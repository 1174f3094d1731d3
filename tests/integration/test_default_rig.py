"""`stage-emu serve` with no arguments: the bundled rig's MP-285 and MS2000 answer at 9600 baud."""

from __future__ import annotations

import time
from pathlib import Path

import serial

from tests.support.daemon import start_daemon

CHAR_9600 = 10 / 9600
#: event-loop wake-ups and pyserial reads on a loaded CI machine
SLACK_S = 0.05


def test_default_rig_serves_both_controllers(tmp_path: Path) -> None:
    daemon = start_daemon(tmp_path, [], expect_ports=2)
    try:
        served = [(p["device"], p["profile"]) for p in daemon.ports]
        assert served == [("mp285", "mp285"), ("ms2000", "ms2000")]

        with serial.Serial(daemon.port("mp285"), 9600, timeout=2) as mp285:
            started = time.monotonic()
            mp285.write(b"c\r")
            reply = mp285.read(13)
            elapsed = time.monotonic() - started
        # power-on position 0, 0, 0 as three little-endian int32 and CR (MP-10, MP-11)
        assert reply == bytes(12) + b"\r"
        # 2 characters in, 13 out, each 10 bits at 9600 baud
        assert 15 * CHAR_9600 * 0.9 <= elapsed <= 15 * CHAR_9600 + SLACK_S

        with serial.Serial(daemon.port("ms2000"), 9600, timeout=2) as ms2000:
            ms2000.write(b"W X Y\r")
            assert ms2000.read_until(b"\n") == b":A 0 0\r\n"
            ms2000.write(b"FOO\r")
            assert ms2000.read_until(b"\n") == b":N-1\r\n"
    finally:
        assert daemon.stop() == 0
