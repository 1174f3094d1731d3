"""Record sessions with `stage-emu proxy`, driven by a scripted host program.

    python scripts/record_sessions.py                  # the suite's cases, recorded from the emulator
    python scripts/record_sessions.py --real /dev/ttyUSB0 --device ms2000 --out ms2000-lab.jsonl

Without --real it records the conformance suite's sessions (tests/conformance/DEVICE/sessions/
basic.jsonl) from the in-process emulator, `stageemu://DEVICE`; with --real, the same host script
against a controller. Each script first puts the controller in a known state (origin, mode, speeds),
so a session replays on another unit too, and spaces its polls well away from a move's end: a poll
answered a millisecond before or after the move ends would differ between runs by chance.
"""

from __future__ import annotations

import argparse
import json
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import serial

from protocols.mp285 import Move, SetVelocity

ROOT = Path(__file__).resolve().parents[1]
SESSIONS = ROOT / "tests" / "conformance"
STOP_TIMEOUT_S = 10.0


def _ask(port: serial.Serial, data: bytes, size: int) -> bytes:
    port.write(data)
    reply = port.read(size)
    if len(reply) != size:
        raise RuntimeError(f"{data!r}: expected {size} bytes, got {reply!r}")
    return reply


def _line(port: serial.Serial, command: bytes) -> bytes:
    port.write(command)
    reply = port.read_until(b"\r\n")
    if not reply.endswith(b"\r\n"):
        raise RuntimeError(f"{command!r}: incomplete reply {reply!r}")
    return reply


def _pause(seconds: float) -> None:
    """The host's own pacing (what a session records), not a wait for a condition."""
    time.sleep(seconds)


def drive_mp285(port: serial.Serial) -> None:
    """Absolute mode, origin here, 200 µm/s; positions around a 10 µm move and back; a bad command;
    an idle ^C."""
    _ask(port, b"a\r", 1)
    _ask(port, b"o\r", 1)
    _ask(port, SetVelocity.of(200).encode(), 1)
    _ask(port, b"c\r", 13)
    _ask(port, Move(250, 0, 0).encode(), 1)  # 10 µm: 50 ms, then the settle time, then CR
    _ask(port, b"c\r", 13)
    _ask(port, Move(0, 0, 0).encode(), 1)
    _ask(port, b"c\r", 13)
    _ask(port, b"x\r", 2)  # not a command: error '4'
    _ask(port, b"\x03", 1)  # ^C while idle: CR


def drive_ms2000(port: serial.Serial) -> None:
    """Zero here, 1 mm/s; a command typed a byte per millisecond; a move polled early (busy) and late
    (done); two commands in one write; a move back; an unknown command."""
    _line(port, b"Z\r")
    for byte in b"W X Y\r":
        port.write(bytes((byte,)))
        _pause(0.001)
    port.read_until(b"\r\n")
    _line(port, b"S X=1 Y=1\r")
    for move in (b"M X=1000 Y=-500\r", b"R X=-1000 Y=500\r"):
        _line(port, move)  # 0.1 mm at 1 mm/s: well over 100 ms
        _line(port, b"/\r")
        _pause(0.04)
        _line(port, b"/\r")
        _pause(0.8)
        if _line(port, b"/\r") != b"N\r\n":
            raise RuntimeError("the move has not ended after 0.8 s")
        port.write(b"W X\rW Y\r")
        port.read_until(b"\r\n")
        port.read_until(b"\r\n")
    _line(port, b"W X Y\r")
    _line(port, b"FOO\r")


HOSTS: dict[str, Callable[[serial.Serial], None]] = {"mp285": drive_mp285, "ms2000": drive_ms2000}


@contextmanager
def running_proxy(real: str, family: str, link: Path, record: Path, *extra: str) -> Iterator[dict[str, Any]]:
    """`stage-emu proxy` as a subprocess; yields its announcement and stops it with SIGTERM."""
    command = [sys.executable, "-m", "emulator.cli", "proxy", "--real", real, "--device", family]
    command += ["--link", str(link), "--record", str(record), *extra]
    proc = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        assert proc.stdout is not None and proc.stderr is not None
        line = proc.stdout.readline()
        if not line:
            raise RuntimeError(f"the proxy did not start: {proc.stderr.read().decode().strip()}")
        yield json.loads(line)
    finally:
        proc.send_signal(signal.SIGTERM)
        _out, err = proc.communicate(timeout=STOP_TIMEOUT_S)
        if proc.returncode != 0:
            raise RuntimeError(f"the proxy exited with {proc.returncode}: {err.decode().strip()}")


def record(real: str, family: str, path: Path, baud: int | None = None) -> None:
    """Record HOSTS[family] run through a proxy in front of `real` (at `baud`, default the
    profile's 9600) into `path`."""
    extra = () if baud is None else ("--baud", str(baud))
    with tempfile.TemporaryDirectory() as work:
        link = Path(work) / "link"
        with (
            running_proxy(real, family, link, path, *extra) as info,
            serial.Serial(info["path"], baud or 9600, timeout=2) as port,
        ):
            HOSTS[family](port)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--real", help="a controller's port (default: the in-process emulator)")
    parser.add_argument("--device", choices=sorted(HOSTS), help="with --real: which controller")
    parser.add_argument("--out", type=Path, help="with --real: the session file")
    parser.add_argument("--baud", type=int, help="with --real: its baud rate (default 9600)")
    args = parser.parse_args()
    if args.real:
        if not (args.device and args.out):
            parser.error("--real needs --device and --out")
        record(args.real, args.device, args.out, args.baud)
        return
    for family in HOSTS:
        path = SESSIONS / family / "sessions" / "basic.jsonl"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.unlink(missing_ok=True)
        record(f"stageemu://{family}", family, path)
        print(path)


if __name__ == "__main__":
    main()
