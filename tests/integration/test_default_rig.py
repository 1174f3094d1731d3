"""`stage-emu serve` with no arguments: the bundled rig's MP-285 and MS2000 answer at 9600 baud."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
import serial

from emulator.control_client import ControlClient
from tests.support.daemon import start_daemon

CHAR_9600 = 10 / 9600
#: the runner may release a byte up to half a millisecond before its instant (emulator/hosting/walltimer.py)
EARLY_S = 0.001
#: generous: only a hang takes this long on any machine
HANG_S = 10.0


def test_default_rig_serves_both_controllers(tmp_path: Path) -> None:
    daemon = start_daemon(tmp_path, [], expect_ports=2)
    try:
        served = [(p["device"], p["profile"]) for p in daemon.ports]
        assert served == [("mp285", "mp285"), ("ms2000", "ms2000")]

        with (
            ControlClient(daemon.control_path) as watcher,
            serial.Serial(daemon.port("mp285"), 9600, timeout=HANG_S) as mp285,
        ):
            watcher.subscribe("mp285", traffic=True)  # the device's own instants of each exchange
            started = time.monotonic()
            mp285.write(b"c\r")
            reply = mp285.read(13)
            elapsed = time.monotonic() - started
            records = watcher.events(timeout=HANG_S)
            request, answer = next(records), next(records)
        # power-on position 0, 0, 0 as three little-endian int32 and CR (MP-10, MP-11)
        assert reply == bytes(12) + b"\r"
        # 2 characters in, 13 out, each 10 bits at 9600 baud: the request is complete when its
        # second character is, and the reply's last byte leaves 13 characters later
        assert (request["dir"], bytes.fromhex(request["hex"])) == ("rx", b"c\r")
        assert (answer["dir"], bytes.fromhex(answer["hex"])) == ("tx", reply)
        assert answer["t"] - request["t"] == pytest.approx(13 * CHAR_9600, abs=2e-6)
        # the host's side, which load can only lengthen: never sooner than the wire carries them
        assert elapsed >= 15 * CHAR_9600 - EARLY_S

        with serial.Serial(daemon.port("ms2000"), 9600, timeout=HANG_S) as ms2000:
            ms2000.write(b"W X Y\r")
            assert ms2000.read_until(b"\n") == b":A 0 0\r\n"
            ms2000.write(b"FOO\r")
            assert ms2000.read_until(b"\n") == b":N-1\r\n"
    finally:
        assert daemon.stop() == 0
