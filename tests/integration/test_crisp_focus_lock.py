"""The CRISP issue's "done means": `stage-emu serve --profile ms2000-crisp` locks focus by hand
(`LK F=83` … `LK X?` → `:A F`) and holds it while `stage-emu ctl input ms2000-crisp crisp
drift_um_per_s=0.5` drifts the sample (MS-CRISP-2, MS-CRISP-3, MS-CRISP-6)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import serial

from tests.support.daemon import ROOT, start_daemon

DEVICE = "ms2000-crisp"
DRIFT_UM_PER_S = 0.5
#: device time the drift runs; the clock is run 10 times faster than wall time meanwhile
DRIFT_S = 10.0
#: device seconds the lock may take to settle in focus (it takes well under one)
LOCK_S = 5.0
#: generous: only a hang takes this long on any machine
HANG_S = 10.0
#: a command's whole run, its start included: generous, a loaded machine has taken ten seconds to
#: start a Python process
RUN_S = 60.0


def ask(port: serial.Serial, command: bytes) -> bytes:
    port.write(command)
    reply = port.read_until(b"\r\n")
    assert reply.endswith(b"\r\n"), f"{command!r}: incomplete reply {reply!r}"
    return reply


def test_lock_holds_focus_against_drift(tmp_path: Path) -> None:
    daemon = start_daemon(tmp_path, ["--profile", DEVICE], expect_ports=1)
    try:
        control = daemon.control()
        with serial.Serial(daemon.port(DEVICE), 9600, timeout=HANG_S) as port:
            assert ask(port, b"LK X?\r") == b":A I\r\n"
            assert ask(port, b"LK F=83\r") == b":A\r\n"
            deadline = float(control.clock()["now"]) + LOCK_S  # device time: load cannot eat it
            while ask(port, b"LK X?\r") != b":A F\r\n":
                assert float(control.clock()["now"]) < deadline, "no focus lock"
            result = subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "emulator.cli",
                    "ctl",
                    "--control",
                    str(daemon.control_path),
                    "input",
                    DEVICE,
                    "crisp",
                    f"drift_um_per_s={DRIFT_UM_PER_S}",
                ],
                cwd=ROOT,
                env={**os.environ, "PYTHONPATH": str(ROOT)},
                capture_output=True,
                text=True,
                timeout=RUN_S,
            )
            assert result.returncode == 0, result.stderr
            start = float(control.clock()["now"])  # the drift runs from before this
            control.clock(10.0)
            while float(control.clock()["now"]) - start < DRIFT_S:
                assert ask(port, b"LK X?\r") == b":A F\r\n"
            control.clock(1.0)
            assert ask(port, b"LK X?\r") == b":A F\r\n"
            followed_units = int(ask(port, b"W Z\r")[3:-2])
            seen = control.get(DEVICE, "crisp")
            # the sample drifted at least DRIFT_S × 0.5 µm and the focus axis followed it (0.1 µm
            # units), within an encoder count or two
            assert seen["state"] == "F" and seen["surface_um"] >= DRIFT_UM_PER_S * DRIFT_S
            assert abs(followed_units - seen["surface_um"] * 10) <= 3
    finally:
        assert daemon.stop() == 0
