"""Timed internal events of the model: a heap of callbacks run in due order by `advance(now)`.

Each callback receives the instant it was due, so everything it emits is stamped with that instant
(device contract). A callback may schedule further events, including ones already due: they run in
the same `run_due` pass, in order.
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Callable
from dataclasses import dataclass, field


@dataclass(order=True)
class Timer:
    due: float
    seq: int
    action: Callable[[float], None] = field(compare=False)
    cancelled: bool = field(default=False, compare=False)

    def cancel(self) -> None:
        self.cancelled = True


class Scheduler:
    def __init__(self) -> None:
        self._heap: list[Timer] = []
        self._seq = itertools.count()

    def at(self, due: float, action: Callable[[float], None]) -> Timer:
        timer = Timer(due, next(self._seq), action)
        heapq.heappush(self._heap, timer)
        return timer

    def next_due(self) -> float | None:
        while self._heap and self._heap[0].cancelled:
            heapq.heappop(self._heap)
        return self._heap[0].due if self._heap else None

    def run_due(self, now: float) -> None:
        while True:
            due = self.next_due()
            if due is None or due > now:
                return
            timer = heapq.heappop(self._heap)
            timer.action(timer.due)

    def clear(self) -> None:
        for timer in self._heap:
            timer.cancelled = True
        self._heap.clear()
