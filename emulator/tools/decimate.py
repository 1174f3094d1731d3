"""Bounded series for `stage-emu plot`: however long the log, a figure draws a bounded number of
points, and memory holds no more while the log is read.

`Buckets` keeps every item until it holds `limit` of them; past that, it splits the time it has seen
into at most `limit // 4` equal buckets and keeps in each only what its policy picks: `ends` (the
first and last item) or `extremes` (those and the items of the lowest and highest value: min/max
per bucket, the classic way to thin a line without losing its peaks). When a new item falls beyond
the last bucket, the bucket width doubles and neighbours merge, so the whole span is always covered
by at most that many buckets, in one pass, in any order of arrival.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Generic, TypeVar

T = TypeVar("T")
#: an item as (time, value, the item): value orders `extremes`
Entry = tuple[float, float, T]
Policy = Callable[[list[Entry[T]]], list[Entry[T]]]


def ends(entries: list[Entry[T]]) -> list[Entry[T]]:
    """The first and the last item of a bucket (by time; ties: in order of arrival)."""
    if len(entries) <= 2:
        return entries
    first = min(range(len(entries)), key=lambda i: entries[i][0])
    last = max(range(len(entries)), key=lambda i: (entries[i][0], i))
    return [entries[i] for i in sorted({first, last})]


def extremes(entries: list[Entry[T]]) -> list[Entry[T]]:
    """The first, last, lowest and highest items of a bucket, in order of arrival."""
    if len(entries) <= 4:
        return entries
    picked = {
        min(range(len(entries)), key=lambda i: entries[i][0]),
        max(range(len(entries)), key=lambda i: (entries[i][0], i)),
        min(range(len(entries)), key=lambda i: entries[i][1]),
        max(range(len(entries)), key=lambda i: entries[i][1]),
    }
    return [entries[i] for i in sorted(picked)]


class Buckets(Generic[T]):
    """Items by time, at most `limit` of them kept (see the module's docstring)."""

    def __init__(self, limit: int, policy: Policy[T]) -> None:
        self.limit = limit
        self.policy = policy
        #: every item added (kept or not)
        self.added = 0
        self._exact: list[Entry[T]] | None = []
        self._origin = 0.0
        self._width = 0.0
        self._buckets: dict[int, list[Entry[T]]] = {}

    @property
    def decimated(self) -> bool:
        return self._exact is None

    def add(self, t: float, item: T, value: float = 0.0) -> None:
        self.added += 1
        entry = (t, value, item)
        if self._exact is not None:
            self._exact.append(entry)
            if len(self._exact) > self.limit:
                self._bucket(self._exact)
            return
        self._put(entry)

    def items(self) -> list[T]:
        """What is kept, in time order (ties: in order of arrival)."""
        if self._exact is not None:
            kept = self._exact
        else:
            kept = [entry for index in sorted(self._buckets) for entry in self._buckets[index]]
        return [item for _, _, item in sorted(kept, key=lambda entry: entry[0])]

    def __len__(self) -> int:
        return len(self._exact) if self._exact is not None else sum(map(len, self._buckets.values()))

    def _bucket(self, entries: list[Entry[T]]) -> None:
        self._exact = None
        times = [t for t, _, _ in entries]
        self._origin = min(times)
        span = max(times) - self._origin
        count = max(1, self.limit // 4)
        self._width = span / count if span > 0 else 1e-9
        for entry in entries:
            self._put(entry)

    def _put(self, entry: Entry[T]) -> None:
        index = math.floor((entry[0] - self._origin) / self._width)
        bucket = self._buckets.setdefault(index, [])
        bucket.append(entry)
        if len(bucket) > 4:
            bucket[:] = self.policy(bucket)
        while len(self._buckets) > max(1, self.limit // 4):
            self._widen()

    def _widen(self) -> None:
        """Double the width: neighbours merge, each merged bucket thinned by the policy again."""
        self._width *= 2
        merged: dict[int, list[Entry[T]]] = {}
        for index, entries in self._buckets.items():
            merged.setdefault(index // 2, []).extend(entries)
        self._buckets = {index: self.policy(entries) for index, entries in merged.items()}
