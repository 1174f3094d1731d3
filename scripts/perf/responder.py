"""The floor's process: a PTY whose master is answered by a plain blocking loop that parses nothing.

It reads a script of (request length, reply hex) pairs as JSON on stdin, prints the slave's path
once it can answer, then for each request counts that many bytes and writes that reply (the script
cycles). Standard library only, so that it starts in milliseconds (scripts/perf/floor.py runs it).
"""

from __future__ import annotations

import itertools
import json
import os
import sys
import tty


def main() -> None:
    script = [(length, bytes.fromhex(reply)) for length, reply in json.load(sys.stdin)]
    master, slave = os.openpty()
    tty.setraw(slave)
    # `slave` stays open for the floor's life, as a real port's driver would be: with no slave fd
    # open, a read on the master fails with EIO until the host has opened the port
    print(os.ttyname(slave), flush=True)
    pending = 0
    for length, reply in itertools.cycle(script):
        while pending < length:
            pending += len(os.read(master, 4096))
        pending -= length
        os.write(master, reply)


if __name__ == "__main__":
    main()
