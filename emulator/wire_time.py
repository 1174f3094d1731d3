"""Wire time: how long characters take on the serial line, and pacing by it.

A pseudo-terminal moves bytes at memory speed. With `timing: realistic` the device's output is
released one character at a time, each character arriving when its stop bit ends on a real wire
(`bits_per_char / baud`), and host input is handed to the device no earlier than the end of its own
wire time at the host's rate (bytes of one write back to back). With `timing: fast` both happen at
once. All times are device seconds (emulator/hosting/clock.py).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, fields

from emulator.device import HostLine, LineSettings

REALISTIC = "realistic"
FAST = "fast"
TIMINGS = (REALISTIC, FAST)

_EPSILON = 1e-9


def bits_per_char(data_bits: int = 8, parity: str = "none", stop_bits: float = 1) -> float:
    """Start bit + data bits + parity bit (if any) + stop bits."""
    return 1 + data_bits + (0 if parity == "none" else 1) + stop_bits


def char_time(baud: int, data_bits: int = 8, parity: str = "none", stop_bits: float = 1) -> float:
    """Seconds one character occupies the wire (1.0417 ms at 9600 8N1)."""
    return bits_per_char(data_bits, parity, stop_bits) / baud


def settings_char_time(settings: HostLine, fallback: LineSettings) -> float:
    """Character time of `settings`, taking what a transport cannot see (None) from `fallback`."""
    line = settings.filled(fallback)
    return char_time(line.baud, line.data_bits, line.parity, line.stop_bits)  # type: ignore[arg-type]


@dataclass(slots=True)
class _Run:
    """Bytes sent back to back: byte `start + k` is complete at `first_end + k * per_char`."""

    first_end: float
    per_char: float
    data: bytes
    #: bytes before this index are taken (an index, not a re-slice: a paced run loses one byte per step)
    start: int = 0


class Pacer:
    """Serialises bytes onto one direction of the line and says when each is complete.

    `push(t, data)` queues bytes that become ready to send at device time `t`; they go out after
    whatever is already on the wire. `take_due(now)` pops the (completion time, bytes) runs whose
    characters are complete by `now`. A per-character time of 0 delivers at once (`timing: fast`).
    `len()` is the number of bytes queued and not yet taken (the backlog the runner bounds).
    """

    def __init__(self, per_char: float = 0.0) -> None:
        self.per_char = per_char
        self._runs: deque[_Run] = deque()
        self._wire_free = float("-inf")
        self._size = 0

    def push(self, t: float, data: bytes) -> None:
        if not data:
            return
        start = t if t > self._wire_free else self._wire_free
        per_char = self.per_char
        self._wire_free = start + per_char * len(data)
        self._runs.append(_Run(start + per_char, per_char, bytes(data)))
        self._size += len(data)

    @property
    def wire_free(self) -> float:
        """Device time at which the last queued character is complete."""
        return self._wire_free

    def next_due(self) -> float | None:
        return self._runs[0].first_end if self._runs else None

    def take_due(self, now: float) -> list[tuple[float, bytes]]:
        """Runs of characters complete by `now`, each as (completion time of its last byte, bytes)."""
        taken: list[tuple[float, bytes]] = []
        runs = self._runs
        while runs:
            run = runs[0]
            if run.first_end > now + _EPSILON:
                break
            if run.per_char <= 0:  # fast timing: the run arrives whole
                taken.append((run.first_end, run.data if run.start == 0 else run.data[run.start :]))
                self._size -= len(run.data) - run.start
                runs.popleft()
                continue
            left = len(run.data) - run.start
            count = min(left, int((now + _EPSILON - run.first_end) / run.per_char) + 1)
            end = run.start + count
            taken.append((run.first_end + (count - 1) * run.per_char, run.data[run.start : end]))
            self._size -= count
            if count == left:
                runs.popleft()
            else:
                run.start += count
                run.first_end += count * run.per_char
        return taken

    def take_each_due(self, now: float) -> list[tuple[float, int]]:
        """Like `take_due`, one (completion time, byte) per character."""
        result: list[tuple[float, int]] = []
        for end, data in self.take_due(now):
            first = end - (len(data) - 1) * self.per_char
            result.extend((first + i * self.per_char, b) for i, b in enumerate(data))
        return result

    def clear(self) -> None:
        self._runs.clear()
        self._wire_free = float("-inf")
        self._size = 0

    def __len__(self) -> int:
        return self._size


def mismatches(device: LineSettings, host: HostLine) -> list[str]:
    """Names of the settings in which a host visibly differs from the device (unseen ones match)."""
    in_effect = host.filled(device)
    return [f.name for f in fields(device) if getattr(in_effect, f.name) != getattr(device, f.name)]
