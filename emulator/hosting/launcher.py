"""Start `stage-emu serve` as a subprocess the way a user would, and wait for its readiness lines.

Used by the test suites, the benchmark and the torture script (and by anyone driving a daemon from
Python). The daemon's stderr is drained by a thread into `<workdir>/daemon.log` and memory, never
left in an unread pipe: a daemon that logs a lot must not block on a full pipe.
"""

from __future__ import annotations

import json
import os
import selectors
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from emulator.control_client import ControlClient

STARTUP_TIMEOUT = 20.0


class LogPump(threading.Thread):
    """Copies the daemon's stderr, line by line, to a file and to memory; wakes waiters."""

    def __init__(self, stream: IO[bytes], path: Path) -> None:
        super().__init__(daemon=True, name="stage-emu-log")
        self._stream = stream
        self.path = path
        self.lines: list[str] = []
        self.changed = threading.Condition()

    def run(self) -> None:
        with open(self.path, "w", encoding="utf-8") as copy:
            for raw in self._stream:
                line = raw.decode("utf-8", "replace").rstrip("\n")
                copy.write(line + "\n")
                copy.flush()
                with self.changed:
                    self.lines.append(line)
                    self.changed.notify_all()

    def wait_line(self, needle: str, start: int, timeout: float) -> tuple[int, str] | None:
        """The first line at index >= `start` containing `needle` (index, line), or None."""
        deadline = time.monotonic() + timeout
        with self.changed:
            while True:
                for index in range(start, len(self.lines)):
                    if needle in self.lines[index]:
                        return index, self.lines[index]
                start = len(self.lines)
                remaining = deadline - time.monotonic()
                if remaining <= 0 or not self.is_alive():
                    return None
                self.changed.wait(remaining)


@dataclass
class RunningDaemon:
    proc: subprocess.Popen[bytes]
    ports: list[dict[str, Any]]
    control_path: Path
    workdir: Path
    log: LogPump
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
        self._clients.clear()
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        code = self.proc.wait(timeout)
        self.log.join(timeout)
        return code

    def stderr(self) -> str:
        """What the daemon logged so far (all of it once it has stopped)."""
        with self.log.changed:
            return "".join(line + "\n" for line in self.log.lines)


def start_daemon(
    workdir: Path,
    args: list[str],
    expect_ports: int,
    *,
    entry: str = "emulator.cli",
    cwd: Path | None = None,
    env: dict[str, str] | None = None,
    preexec_fn: Callable[[], None] | None = None,
) -> RunningDaemon:
    """Run `python -m ENTRY serve ARGS` with its links, socket and state under `workdir` (the
    state only unless ARGS has `--no-state`); returns once `expect_ports` readiness lines were
    printed. `env` replaces the environment; `preexec_fn` runs in the child before exec (e.g. to
    lower a resource limit)."""
    workdir.mkdir(parents=True, exist_ok=True)
    control = workdir / "control.sock"
    command = [sys.executable, "-m", entry, "serve", *args, "--control", str(control)]
    command += ["--link-dir", str(workdir / "links")]
    if "--no-state" not in args:
        command += ["--state-dir", str(workdir / "state")]
    proc = subprocess.Popen(
        command, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, preexec_fn=preexec_fn
    )
    assert proc.stderr is not None
    log = LogPump(proc.stderr, workdir / "daemon.log")
    log.start()
    try:
        ports = _read_ready_lines(proc, expect_ports, log)
    except BaseException:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        raise
    return RunningDaemon(proc, ports, control, workdir, log)


def _read_ready_lines(proc: subprocess.Popen[bytes], count: int, log: LogPump) -> list[dict[str, Any]]:
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
                raise TimeoutError(f"daemon not ready in {STARTUP_TIMEOUT} s: {_said(log)}")
            chunk = os.read(fd, 65536)
            if not chunk:
                code = proc.wait()
                log.join(5)
                raise RuntimeError(f"daemon exited ({code}): {_said(log)}")
            buffer += chunk
    finally:
        selector.close()
    return [json.loads(line) for line in buffer.decode().splitlines()]


def _said(log: LogPump) -> str:
    with log.changed:
        return " | ".join(log.lines)


def write_rig(workdir: Path, devices: Sequence[tuple[str, str]], timing: str | None = None) -> Path:
    """`workdir/rig.yaml` with one device per (name, profile), each on its own port, all with
    `timing` when given (written as JSON, which is YAML)."""
    workdir.mkdir(parents=True, exist_ok=True)
    port = {} if timing is None else {"ports": [{"timing": timing}]}
    rig = {"spec": 1, "devices": [{"name": name, "profile": profile, **port} for name, profile in devices]}
    path = workdir / "rig.yaml"
    path.write_text(json.dumps(rig))
    return path
