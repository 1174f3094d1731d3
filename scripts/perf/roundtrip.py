"""Round trips through the PTY (`--timing fast`, pyserial host): the emulator against the floor.

Each case runs `visits` visits of a warm-up and `samples` timed samples, alternating emulator and
floor (E F E F ...), each visit on a freshly opened port. A floor visit replays the transcript of the
emulator visit just before it, so both sides do the same exchanges with the same replies. Reported:
the median over visits of each side's p50 and p99, and as ratios the median over visits of each
visit's emulator/floor ratio (a pair adjacent in time, so slow drift of a shared machine cancels).

Placement: during a visit the responder (every thread of the daemon, or the floor) runs on the least
busy CPU and the host thread on another, so that every round trip crosses CPUs the same way, as
between a host program and an emulator each on its own core. Left to the scheduler, a ping-pong pair
shares a CPU in some visits and not in others, and on a virtual machine the quicker responder can
come out slower (its vCPU halts between requests and takes long to wake): unpinned, the ratios swung
between 0.4 and 7 from one run to the next on the 2-CPU development machine.

References, not targets: the rows once carried p50 ≤ 1.10 × floor and p99 ≤ 1.5 × floor (issue
"Speed"), which a model that follows the controllers' rules cannot meet in CPython (the README's
Performance section shows where the time goes, measured). The regression guard of round trips is
the Python call counts per exchange held by `make test` (tests/unit/test_call_budget.py).
"""

from __future__ import annotations

import statistics
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import serial

from emulator.hosting.launcher import RunningDaemon
from protocols.mp285 import GetPosition, SetVelocity, encode_position
from scripts.perf import inprocess
from scripts.perf.common import (
    BenchError,
    Result,
    ask,
    open_host,
    p50_p99,
    placed,
    quietest_cpus,
    read_reply,
    serve,
)
from scripts.perf.floor import floor_port

WARMUP = 20
#: polls after which a tiny move that has not completed is a hung device
MAX_POLLS = 10_000

#: (request length, reply) of each exchange of a visit, in order: what the floor replays
Transcript = list[tuple[int, bytes]]


class Case(Protocol):
    @property
    def name(self) -> str: ...

    @property
    def device(self) -> str:
        """The daemon's device (and port) the case talks to."""

    def setup(self, port: serial.Serial) -> None:
        """Once, on the emulator's port, before the visits."""

    def sample(self, port: serial.Serial, index: int, log: Transcript, times: list[float]) -> None:
        """The exchanges of sample `index` (counted across visits), each reply checked and logged,
        each timed from its request to its reply (µs, appended to `times`)."""


@dataclass(frozen=True)
class Fixed:
    """One request answered by known bytes."""

    name: str
    device: str
    request: bytes
    reply: bytes

    def setup(self, port: serial.Serial) -> None:
        pass

    def sample(self, port: serial.Serial, index: int, log: Transcript, times: list[float]) -> None:
        reply = exchange(port, self.request, len(self.reply), self.name, times)
        if reply != self.reply:
            raise BenchError(f"{self.name}: answered {reply!r}, expected {self.reply!r}")
        log.append((len(self.request), reply))


@dataclass(frozen=True)
class MoveAndPoll:
    """`M X=<index + 1>` then `/` until `N`; each exchange is timed on its own, since the move's own
    duration (which the polls wait out) is modelling, not a round trip. Targets rise by 0.1 µm (5
    counts or 4), so no move is a backwards one with its anti-backlash detour (MS-57)."""

    name: str = "ms2000 M X + / to N"
    device: str = "ms2000"

    def setup(self, port: serial.Serial) -> None:
        # ramp time AC 1 ms: a 5-count step then lands in 0.3 ms, within a few polls
        ask(port, b"AC X=1\r", b":A\r\n")

    def sample(self, port: serial.Serial, index: int, log: Transcript, times: list[float]) -> None:
        request = f"M X={index + 1}\r".encode()
        reply = exchange(port, request, 4, "M", times)
        if reply != b":A\r\n":
            raise BenchError(f"{request!r} answered {reply!r}")
        log.append((len(request), reply))
        for _ in range(MAX_POLLS):
            reply = exchange(port, b"/\r", 3, "/", times)
            log.append((2, reply))
            if reply == b"N\r\n":
                return
            if reply != b"B\r\n":
                raise BenchError(f"/ answered {reply!r} during a move")
        raise BenchError(f"{request!r}: still busy after {MAX_POLLS} polls")


def exchange(port: serial.Serial, request: bytes, length: int, what: str, times: list[float]) -> bytes:
    """Write `request`, read a reply of `length` bytes; the time between, in µs, goes to `times`."""
    start = time.perf_counter()
    port.write(request)
    reply = read_reply(port, length, what)
    times.append((time.perf_counter() - start) * 1e6)
    return reply


W_X_Y = Fixed("ms2000 W X Y", "ms2000", b"W X Y\r", b":A 0 0\r\n")
#: in this order: the move comes last, after the cases that read X as 0
CASES: tuple[Case, ...] = (
    Fixed("mp285 c", "mp285", GetPosition().encode(), encode_position(0, 0, 0)),
    Fixed("mp285 V", "mp285", SetVelocity.of(1000).encode(), b"\r"),
    W_X_Y,
    Fixed("ms2000 S X?", "ms2000", b"S X?\r", b":A X=5.145600\r\n"),
    MoveAndPoll(),
)


def run(workdir: Path, visits: int, samples: int, move_samples: int) -> list[Result]:
    daemon = serve(workdir, ["--profile", "mp285", "--profile", "ms2000", "--timing", "fast"], 2)
    try:
        results = []
        for case in CASES:
            with open_host(daemon.port(case.device)) as port:
                case.setup(port)
            count = move_samples if isinstance(case, MoveAndPoll) else samples
            results.append(measure(case, daemon, visits, count))
    finally:
        daemon.stop()
    results.append(event_loop_share(W_X_Y, visits, samples))
    fixed = [case for case in CASES if isinstance(case, Fixed)]
    floors = {result.case: result.reference[0] for result in results}
    results += inprocess.rows(
        [(case.name, case.device, case.request, case.reply) for case in fixed],
        {case.name: floors[f"round trip {case.name}"] for case in fixed},
        visits * samples,
    )
    return results


def event_loop_share(case: Fixed, visits: int, samples: int) -> Result:
    """For reference, no target: the floor's answering moved into an asyncio loop (a reader callback
    on the master, as the daemon serves its ports), against the floor. This part of the emulator's
    ratio is the event loop's, before any parsing or modelling."""
    script = [(len(case.request), case.reply)]
    looped: list[tuple[float, float]] = []
    floors: list[tuple[float, float]] = []
    for visit in range(visits):
        first = visit * (WARMUP + samples)
        cpus = quietest_cpus()
        device, host = {cpus[0]}, {cpus[1 % len(cpus)]}
        with floor_port(script, event_loop=True) as (path, pid), placed({0: host, pid: device}):
            looped.append(p50_p99(_visit(path, case, first, samples)[0]))
        with floor_port(script) as (path, pid), placed({0: host, pid: device}):
            floors.append(p50_p99(_visit(path, case, first, samples)[0]))
    ratios = [(e[0] / f[0], e[1] / f[1]) for e, f in zip(looped, floors, strict=True)]
    return Result(
        case=f"round trip {case.name} answered in an asyncio loop",
        unit="µs",
        emulator=_median_of_visits(looped),
        reference=_median_of_visits(floors),
        checks=(),
        details={"looped_us_by_visit": looped, "floor_us_by_visit": floors, "ratios_by_visit": ratios},
        info=(
            ("p50 ratio", statistics.median(r[0] for r in ratios)),
            ("p99 ratio", statistics.median(r[1] for r in ratios)),
        ),
    )


def measure(case: Case, daemon: RunningDaemon, visits: int, samples: int) -> Result:
    emulated: list[tuple[float, float]] = []
    floors: list[tuple[float, float]] = []
    exchanges = 0
    for visit in range(visits):
        first = visit * (WARMUP + samples)
        cpus = quietest_cpus()
        device, host = {cpus[0]}, {cpus[1 % len(cpus)]}
        with placed({0: host, daemon.proc.pid: device}):
            times, log = _visit(daemon.port(case.device), case, first, samples)
        with floor_port(log) as (path, pid), placed({0: host, pid: device}):
            floor_times, _ = _visit(path, case, first, samples)
        emulated.append(p50_p99(times))
        floors.append(p50_p99(floor_times))
        exchanges += len(log)
    ratios = [(e[0] / f[0], e[1] / f[1]) for e, f in zip(emulated, floors, strict=True)]
    p50_ratio = statistics.median(r[0] for r in ratios)
    p99_ratio = statistics.median(r[1] for r in ratios)
    return Result(
        case=f"round trip {case.name}",
        unit="µs",
        emulator=_median_of_visits(emulated),
        reference=_median_of_visits(floors),
        checks=(),
        details={
            "visits": visits,
            "samples_per_visit": samples,
            "exchanges_per_sample": exchanges / (visits * (WARMUP + samples)),
            "emulator_us_by_visit": emulated,
            "floor_us_by_visit": floors,
            "ratios_by_visit": ratios,
        },
        info=(("p50 ratio", p50_ratio), ("p99 ratio", p99_ratio)),
    )


def _visit(path: str, case: Case, first: int, samples: int) -> tuple[list[float], Transcript]:
    """Warm-up then `samples` samples on a fresh port; the round-trip time of each of their
    exchanges in µs, and the transcript of all."""
    log: Transcript = []
    times: list[float] = []
    with open_host(path) as port:
        for index in range(first, first + WARMUP):
            case.sample(port, index, log, [])
        for index in range(first + WARMUP, first + WARMUP + samples):
            case.sample(port, index, log, times)
    return times, log


def _median_of_visits(figures: list[tuple[float, float]]) -> tuple[float, float]:
    return statistics.median(f[0] for f in figures), statistics.median(f[1] for f in figures)
