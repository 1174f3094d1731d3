"""The PTY transport gives up the CPU after the first write of a loop turn only
(emulator/hosting/transports/pty.py `yield_once_per_turn`): a yield per write let a burst of one-byte
replies cost a time slice per byte on a busy machine."""

from __future__ import annotations

import asyncio

import pytest

from emulator.hosting.transports import pty


def test_a_burst_of_writes_yields_once_per_loop_turn(monkeypatch: pytest.MonkeyPatch) -> None:
    yields: list[int] = []
    monkeypatch.setattr(pty.os, "sched_yield", lambda: yields.append(1))

    async def turns() -> list[int]:
        loop = asyncio.get_running_loop()
        counts = []
        for _ in range(3):
            for _ in range(400):  # one turn's writes: a crashed MP-285 answering 400 bytes (MP-77)
                pty.yield_once_per_turn(loop)
            counts.append(len(yields))
            await asyncio.sleep(0)  # the loop turns
            await asyncio.sleep(0)
        return counts

    assert asyncio.run(turns()) == [1, 2, 3]
