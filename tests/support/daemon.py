"""Start `stage-emu serve` as a subprocess the way a user would, and wait for its readiness lines."""

from __future__ import annotations

import json
import os
import selectors
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from emulator.control import ControlClient

ROOT = Path(__file__).resolve().parents[2]
STARTUP_TIMEOUT = 20.0


@dataclass
class RunningDaemon:
    proc: subprocess.Popen[str]
    ports: list[dict[str, Any]]
    control_path: Path
    workdir: Path
    _clients: list[ControlClient] = field(default_factory=list)

    def port(self, device: str, channel: str = "main") -> str:
        return next(p["path"] for p in self.ports if p["device"] == device and p["port"] == channel)

    def control(self) -> ControlClient:
        client = ControlClient(self.control_path)
        self._clients.append(client)
        return client

    def stop(self, sig: int = signal.SIGTERM, timeout: float = 10.0) -> int:
        for client in self._clients:
            client.close()
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        return self.proc.wait(timeout)

    def stderr(self) -> str:
        assert self.proc.stderr is not None
        return self.proc.stderr.read()


def start_daemon(
    workdir: Path, args: list[str], expect_ports: int, test_devices: bool = False
) -> RunningDaemon:
    """Run `stage-emu serve ARGS` with its links, socket and state under `workdir`."""
    workdir.mkdir(parents=True, exist_ok=True)
    control = workdir / "control.sock"
    entry = ["-m", "tests.support.serve"] if test_devices else ["-m", "emulator.cli"]
    command = [
        sys.executable,
        *entry,
        "serve",
        *args,
        "--control",
        str(control),
        "--link-dir",
        str(workdir / "links"),
        "--state-dir",
        str(workdir / "state"),
    ]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen(
        command, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    ports = _read_ready_lines(proc, expect_ports)
    return RunningDaemon(proc, ports, control, workdir)


def _read_ready_lines(proc: subprocess.Popen[str], count: int) -> list[dict[str, Any]]:
    """Read exactly `count` JSON lines from the daemon's stdout (unbuffered, so nothing is held back)."""
    assert proc.stdout is not None
    fd = proc.stdout.fileno()
    selector = selectors.DefaultSelector()
    selector.register(fd, selectors.EVENT_READ)
    deadline = time.monotonic() + STARTUP_TIMEOUT
    buffer = b""
    try:
        while buffer.count(b"\n") < count:
            remaining = deadline - time.monotonic()
            if remaining <= 0 or not selector.select(remaining):
                proc.kill()
                raise TimeoutError(f"daemon not ready in {STARTUP_TIMEOUT} s: {_stderr(proc)}")
            chunk = os.read(fd, 65536)
            if not chunk:
                raise RuntimeError(f"daemon exited ({proc.wait()}): {_stderr(proc)}")
            buffer += chunk
    finally:
        selector.close()
    return [json.loads(line) for line in buffer.decode().splitlines()]


def _stderr(proc: subprocess.Popen[str]) -> str:
    return proc.stderr.read() if proc.stderr is not None and proc.poll() is not None else ""
