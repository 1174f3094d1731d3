"""The floor's process: a PTY whose master is answered by a plain blocking loop that parses nothing.

It reads a script of (request length, reply hex) pairs as JSON on stdin, prints the slave's path
once it can answer, then for each request counts that many bytes and writes that reply (the script
cycles). Standard library only, so that it starts in milliseconds (scripts/perf/floor.py runs it).

With `--event-loop` the same answering runs inside an asyncio loop (a reader callback on the master,
as the daemon's ports are served): what an event loop alone adds to a round trip, for reference.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import os
import sys
import tty
from collections.abc import Iterator


def main() -> None:
    script = [(length, bytes.fromhex(reply)) for length, reply in json.load(sys.stdin)]
    master, slave = os.openpty()
    tty.setraw(slave)
    # `slave` stays open for the floor's life, as a real port's driver would be: with no slave fd
    # open, a read on the master fails with EIO until the host has opened the port
    print(os.ttyname(slave), flush=True)
    if "--event-loop" in sys.argv[1:]:
        asyncio.run(_answer_in_loop(master, itertools.cycle(script)))
    pending = 0
    for length, reply in itertools.cycle(script):
        while pending < length:
            pending += len(os.read(master, 4096))
        pending -= length
        os.write(master, reply)


async def _answer_in_loop(master: int, script: Iterator[tuple[int, bytes]]) -> None:
    os.set_blocking(master, False)
    pending = 0
    length, reply = next(script)

    def readable() -> None:
        nonlocal pending, length, reply
        pending += len(os.read(master, 4096))
        while pending >= length:
            pending -= length
            os.write(master, reply)
            length, reply = next(script)

    asyncio.get_running_loop().add_reader(master, readable)
    await asyncio.Event().wait()  # until killed


if __name__ == "__main__":
    main()
