"""The torture suite's attack on the in-process `stageemu://` port's write path (no daemon): writes of
random bytes and random sizes up to 64 KiB, each on a factory-fresh device of either family, at
fast timing and at realistic timing (time-scaled), blocking, non-blocking (`write_timeout=0`) or
with a short `write_timeout`, while a thread reads. Every write must return within its wire time
plus a margin, with the count or exception pyserial promises, and the device must answer after it.
(A write that filled the emulated transmit buffer used to wait forever at fast timing.)
"""

from __future__ import annotations

import json
import random
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import serial

import emulator.urlhandler  # noqa: F401  (registers stageemu://)
from scripts.soak.attacks import Outcome

FAMILIES = ("mp285", "ms2000")
#: device seconds per wall second at realistic timing: 64 KiB at 9600 baud is 0.7 s of wall time
SCALE = 100.0
CHAR_9600 = 10 / 9600
LARGEST = 65536
#: wall seconds a write may take beyond its wire time before it counts as a hang
MARGIN_S = 5.0
#: the probe's read timeouts: a pause that ends what the recovery set off, and the answer's bound
QUIET_S = 0.1
ANSWER_S = 2.0
DRAIN_READS = 20
#: the longest MP-285 frame: a 255-vector program download, `d p n <16n bytes> CR`
MP285_LONGEST_FRAME = 4 + 16 * 255
#: blocking, non-blocking, and short enough to expire on a large realistic write
WRITE_TIMEOUTS = (None, 0.0, 0.05)


@dataclass
class _Write:
    family: str
    timing: str
    size: int
    write_timeout: float | None
    #: bytes the write returned, "timeout" (SerialTimeoutException), "hang" or the error's text
    result: int | str
    seconds: float
    answers: bool


def _url(family: str, timing: str) -> str:
    return f"stageemu://{family}?timing=fast" if timing == "fast" else f"stageemu://{family}?scale={SCALE:g}"


def _answers(port: serial.Serial, family: str) -> bool:
    """A well-formed answer after the random bytes, a few tries: first what ends where the bytes
    left the device, then a query whose reply shape is known. An MP-285 may be inside a frame (a
    program download is up to 4084 bytes, with no inter-byte timeout: MP-25), so CRs fill it, and a
    ^C halts a move the bytes started (MP-48); an MS2000 gets a CR that ends its line (or a pending
    0xFF) and leaves low-level mode, which the bytes can enter (MS-119)."""
    if family == "mp285":
        recover, request, length, ending = b"\r" * MP285_LONGEST_FRAME + b"\x03", b"c\r", 13, b"\r"
    else:
        recover, request, length, ending = b"\r\xff\x41\r", b"W X\r", 0, b"\r\n"
    port.write_timeout = None
    port.reset_output_buffer()
    for _ in range(5):
        port.write(recover)
        port.timeout = QUIET_S
        for _ in range(DRAIN_READS):  # what the recovery set off (bounded: a device may keep talking)
            if not port.read(1 << 16):
                break
        port.timeout = ANSWER_S
        port.write(request)
        got = port.read(length) if length else port.read_until(ending)
        if got.endswith(ending) and (not length or len(got) == length):
            return True
    return False


def _one(family: str, timing: str, data: bytes, write_timeout: float | None) -> _Write:
    """One write on a fresh port with a reader draining it; a write still blocked after its bound
    is a hang."""
    port: serial.Serial = serial.serial_for_url(
        _url(family, timing), 9600, timeout=0.02, write_timeout=write_timeout
    )
    stop = threading.Event()

    def drain() -> None:
        while not stop.is_set():
            port.read(4096)

    reader = threading.Thread(target=drain, daemon=True)
    results: list[int | str] = []

    def write() -> None:
        try:
            results.append(port.write(data) or 0)  # typed int | None: ours always counts
        except serial.SerialTimeoutException:
            results.append("timeout")
        except (serial.SerialException, ValueError) as exc:
            results.append(f"error: {exc}")

    writer = threading.Thread(target=write, daemon=True)
    wire_s = 0.0 if timing == "fast" else len(data) * CHAR_9600 / SCALE
    start = time.monotonic()
    reader.start()
    writer.start()
    writer.join(wire_s + MARGIN_S)
    seconds = time.monotonic() - start
    stop.set()
    if writer.is_alive():  # left open: a write spinning with the port's lock would block close too
        return _Write(family, timing, len(data), write_timeout, "hang", seconds, False)
    reader.join()
    try:
        answers = _answers(port, family)
    finally:
        port.close()
    return _Write(family, timing, len(data), write_timeout, results[0], seconds, answers)


def _problem(write: _Write) -> str | None:
    """What is wrong with a write's outcome (None: what pyserial promises for its settings)."""
    result = write.result
    if result == "timeout":
        if write.timing == "fast" or write.write_timeout is None:
            return "timed out"
        return "non-blocking write timed out" if write.write_timeout == 0 else None
    if isinstance(result, str):
        return result
    if not write.answers:
        return "the device no longer answers"
    # the wire takes everything at once (fast timing), or the write waits until it has
    everything = write.timing == "fast" or write.write_timeout is None
    if result > write.size or (everything and result != write.size):
        return f"returned {result} of {write.size} bytes"
    return None


def url_writes(workdir: Path, writes: int = 200, seed: int = 2026) -> Outcome:
    """`writes` random writes, their outcomes logged to `workdir`/writes.jsonl."""
    out = Outcome("writes of up to 64 KiB on stageemu:// ports")
    rng = random.Random(seed)
    workdir.mkdir(parents=True, exist_ok=True)
    slowest = 0.0
    done = total = 0
    with (workdir / "writes.jsonl").open("w", encoding="utf-8") as log:
        for _ in range(writes):
            family, timing = rng.choice(FAMILIES), rng.choice(("fast", "realistic"))
            data = rng.randbytes(rng.randint(1, LARGEST))
            write = _one(family, timing, data, rng.choice(WRITE_TIMEOUTS))
            log.write(json.dumps(write.__dict__) + "\n")
            done, total = done + 1, total + write.size
            if write.timing == "fast":
                slowest = max(slowest, write.seconds)
            problem = _problem(write)
            out.bound(problem is None, f"{family} {timing} {write.size} B: {problem}")
            if write.result == "hang":
                break  # its thread is still blocked: the rest would measure a loaded process
    out.figures.update(seed=seed, writes=done, bytes=total, slowest_fast_write_s=slowest)
    return out
