"""Round-trip latency through the PTY: each device command against a baseline responder, same run.

The baseline is a PTY answered by a plain blocking loop that writes a reply of the right length
without parsing anything: the floor set by the kernel and by pyserial on the host side. Each case
reports median and p99 for the emulator and the baseline and their ratio (lower is better, 1.0 is the
floor). The emulator runs with `--timing fast` so that the figures measure processing, not the
9600-baud wire time that realistic pacing would add on purpose.

    python scripts/bench.py [--rounds N] [--case NAME ...]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import threading
import time
import tty
from dataclasses import dataclass
from pathlib import Path

import serial

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from emulator.launcher import start_daemon  # noqa: E402


@dataclass(frozen=True)
class Case:
    name: str
    profile: str
    command: bytes
    reply_length: int
    baud: int = 9600
    rtscts: bool = False


CASES = (
    Case("mp285 c", "mp285", b"c\r", 13),
    Case("ms2000 W X Y", "ms2000", b"W X Y\r", len(b":A 0 0\r\n")),
)


def baseline_port(command_length: int, reply: bytes) -> tuple[str, threading.Thread]:
    """A PTY whose other end answers every `command_length` bytes with `reply`, unparsed."""
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    os.close(slave)

    def answer() -> None:
        pending = 0
        while True:
            try:
                data = os.read(master, 4096)
            except OSError:
                return
            pending += len(data)
            while pending >= command_length:
                pending -= command_length
                os.write(master, reply)

    thread = threading.Thread(target=answer, daemon=True)
    thread.start()
    return path, thread


def round_trips(path: str, case: Case, rounds: int) -> list[float]:
    with serial.Serial(path, case.baud, timeout=2, rtscts=case.rtscts) as port:
        for _ in range(20):  # warm-up
            port.write(case.command)
            port.read(case.reply_length)
        times = []
        for _ in range(rounds):
            start = time.perf_counter()
            port.write(case.command)
            reply = port.read(case.reply_length)
            times.append(time.perf_counter() - start)
            if len(reply) != case.reply_length:
                raise RuntimeError(f"{case.name}: short reply {reply!r}")
    return times


def summary(times: list[float]) -> tuple[float, float]:
    ordered = sorted(times)
    return statistics.median(ordered), ordered[min(len(ordered) - 1, int(len(ordered) * 0.99))]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=2000)
    parser.add_argument("--case", action="append", choices=[c.name for c in CASES])
    args = parser.parse_args()
    cases = [c for c in CASES if not args.case or c.name in args.case]
    print(f"{'case':<16}{'emulator med/p99 (µs)':>24}{'baseline med/p99 (µs)':>24}{'ratio med/p99':>16}")
    with tempfile.TemporaryDirectory(prefix="stage-emu-bench-") as tmp:
        for case in cases:
            daemon = start_daemon(
                Path(tmp) / case.profile, ["--profile", case.profile, "--timing", "fast"], 1
            )
            try:
                emulated = summary(round_trips(daemon.ports[0]["path"], case, args.rounds))
            finally:
                daemon.stop()
            path, _ = baseline_port(len(case.command), b"\0" * case.reply_length)
            floor = summary(round_trips(path, case, args.rounds))
            print(
                f"{case.name:<16}{emulated[0] * 1e6:>12.0f}/{emulated[1] * 1e6:<11.0f}"
                f"{floor[0] * 1e6:>12.0f}/{floor[1] * 1e6:<11.0f}"
                f"{emulated[0] / floor[0]:>8.2f}/{emulated[1] / floor[1]:.2f}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
