"""`stage-emu trace` on a real traffic log: an MS2000 served with `--log-traffic`, a pyserial host,
`trace --follow` as a subprocess reading along (through a log rotation, SIGUSR1), stopped with
Ctrl-C, and the finished log traced whole."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import serial
from click.testing import CliRunner

from emulator.cli import main
from tests.support.daemon import ROOT, start_daemon

#: generous, a subprocess's start included: a loaded machine has taken ten seconds to start one
WAIT_S = 60.0


class FollowProcess:
    """`stage-emu trace --follow LOG` with its stdout collected by a thread."""

    def __init__(self, log: Path) -> None:
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "emulator.cli", "trace", "--follow", str(log)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env=env,
            text=True,
        )
        self.lines: list[str] = []
        self.changed = threading.Condition()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            with self.changed:
                self.lines.append(line.rstrip("\n"))
                self.changed.notify_all()

    def wait_for(self, needle: str) -> str:
        with self.changed:
            found = self.changed.wait_for(lambda: [x for x in self.lines if needle in x], WAIT_S)
        assert found, f"no line with {needle!r} in {self.lines}"
        return found[-1]

    def interrupt(self) -> tuple[int, str]:
        self.proc.send_signal(signal.SIGINT)
        _, stderr = self.proc.communicate(timeout=WAIT_S)
        return self.proc.returncode, stderr


def ask(port: serial.Serial, command: bytes, reply_end: bytes = b"\n") -> bytes:
    port.write(command)
    return port.read_until(reply_end)


def test_trace_follows_a_served_session_through_a_rotation(tmp_path: Path) -> None:
    log = tmp_path / "traffic.jsonl"
    daemon = start_daemon(
        tmp_path, ["--profile", "ms2000", "--timing", "fast", "--log-traffic", str(log)], expect_ports=1
    )
    follower: FollowProcess | None = None
    try:
        device = daemon.ports[0]["device"]
        with serial.Serial(daemon.port(device), 9600, timeout=5) as port:
            assert ask(port, b"W X Y\r") == b":A 0 0\r\n"
            follower = FollowProcess(log)
            line = follower.wait_for("W X Y [WHERE]")
            assert f"  {device}/main  W X Y [WHERE]  " in line and '"W X Y\\r"  -> ":A 0 0\\r\\n"  [' in line
            log.rename(tmp_path / "traffic.1.jsonl")  # log rotation, then the daemon reopens
            said = len(daemon.stderr().splitlines())
            daemon.proc.send_signal(signal.SIGUSR1)
            assert daemon.log.wait_line("reopened", said, WAIT_S) is not None, daemon.stderr()
            assert ask(port, b"M X=100\r") == b":A\r\n"
            assert '"M X=100\\r"  -> ":A\\r\\n"' in follower.wait_for("[MOVE]")
            follower.wait_for(f"  {device}  * move_complete")
        code, stderr = follower.interrupt()
        assert code == 0 and "Traceback" not in stderr, stderr
    finally:
        if follower is not None and follower.proc.poll() is None:
            follower.proc.kill()
        assert daemon.stop() == 0
    result = CliRunner().invoke(main, ["trace", str(tmp_path / "traffic.1.jsonl"), "--device", device])
    assert result.exit_code == 0, result.output
    assert [line.split(f"  {device}/main  ")[1] for line in result.stdout.splitlines()] == [
        'W X Y [WHERE]  "W X Y\\r"  -> ":A 0 0\\r\\n"  [0.0 ms]'
    ]
