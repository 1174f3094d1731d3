"""The floor a round trip is compared with: a PTY answered without parsing (scripts/perf/responder.py).

It is given the transcript of an emulator visit, (request length, reply) per round trip, and answers
each request with that reply. What is left of a round trip is the kernel, the host's pyserial and a
process switch each way: what no emulator can go below. The responder is a process of its own, as the
daemon is, so it never competes with the host for an interpreter lock.
"""

from __future__ import annotations

import json
import select
import subprocess
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager

from scripts.perf.common import REPLY_TIMEOUT, ROOT, BenchError

Script = Sequence[tuple[int, bytes]]


@contextmanager
def floor_port(script: Script, event_loop: bool = False) -> Iterator[tuple[str, int]]:
    """A responder answering `script` (cycled), in a blocking loop or inside an asyncio loop; yields
    its port's path and its pid, stops it on exit."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "scripts.perf.responder", *(["--event-loop"] if event_loop else [])],
        cwd=ROOT,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
    )
    assert proc.stdin is not None and proc.stdout is not None
    try:
        proc.stdin.write(json.dumps([(length, reply.hex()) for length, reply in script]).encode())
        proc.stdin.close()
        # the path is printed once the responder can answer: no race with the host's open
        if not select.select([proc.stdout], [], [], REPLY_TIMEOUT)[0]:
            raise BenchError(f"floor responder not ready in {REPLY_TIMEOUT} s")
        path = proc.stdout.readline().decode().strip()
        if not path:
            raise BenchError(f"floor responder exited ({proc.wait()}) before it was ready")
        yield path, proc.pid
    finally:
        proc.kill()
        proc.wait()
