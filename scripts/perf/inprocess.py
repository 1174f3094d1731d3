"""For reference, no target: what one exchange of a round-trip case costs inside this process, with
no PTY, no event loop and no other process: the device model alone, then the model behind the
device runner (on a manual clock, through the in-process port of `stageemu://` URLs). Both are
warm (the same exchange thousands of times in a row), so they are lower bounds of what the served
daemon spends.

Set beside the round trips they say why those are references, not targets: a p50 of 1.10 × floor
(the target they once carried) would allow 10 % of the floor's p50 for everything the emulator does
beyond answering, event loop included, and the models alone take about that or more.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

from emulator.device import Device, DeviceServices, LineSettings
from emulator.hosting.clock import ManualClock
from emulator.hosting.runner import DeviceRunner
from emulator.hosting.transports.inprocess import InProcessTransport
from emulator.profiles.profile import load_profile
from emulator.profiles.registry import family
from emulator.wire_time import FAST
from scripts.perf.common import BenchError, Result, p50_p99

HOST = LineSettings(9600, None, None, 1, False, False)
#: device time between two exchanges: past any busy period a reply leaves behind
SPACING_S = 0.05
WARMUP = 200


#: a round-trip case: name, profile, request, reply
Case = tuple[str, str, bytes, bytes]


def rows(cases: Sequence[Case], floors: dict[str, float], samples: int) -> list[Result]:
    """One row per (name, profile, request, reply): model and model + runner µs per exchange, and
    10 % of the floor's p50 in `floors` (by name), what a 1.10 × floor target would allow."""
    results = []
    for name, profile, request, reply in cases:
        model = _timed(_model_exchange(profile, request, reply), samples)
        runner = _timed(_runner_exchange(profile, request, reply), samples)
        results.append(
            Result(
                case=f"in process {name}: model alone",
                unit="µs",
                emulator=model,
                reference=(),
                checks=(),
                details={"runner_and_model_us": runner},
                info=(
                    ("model + runner p50 µs", runner[0]),
                    ("10 % of floor p50 µs", 0.10 * floors[name]),
                ),
            )
        )
    return results


def _make(profile_name: str, now: float) -> Device:
    profile = load_profile(profile_name)
    registered = family(profile.family)
    if registered is None:
        raise BenchError(f"{profile_name}: no device family {profile.family!r}")
    return registered.factory("bench", profile, now, DeviceServices())


#: an exchange to time, and what happens between two exchanges (device time passing), untimed
Exchange = tuple[Callable[[], None], Callable[[], None]]


def _model_exchange(profile_name: str, request: bytes, reply: bytes) -> Exchange:
    device = _make(profile_name, 0.0)
    device.line_changed(HOST, 0.0)
    now = 2.0  # past any power-up silence

    def exchange() -> None:
        device.receive(request, now)
        device.advance(now)
        out = b"".join(e.data for e in device.take_output())
        if out != reply:
            raise BenchError(f"{profile_name} model: {request!r} answered {out!r}, expected {reply!r}")

    def between() -> None:
        nonlocal now
        now += SPACING_S

    return exchange, between


def _runner_exchange(profile_name: str, request: bytes, reply: bytes) -> Exchange:
    clock = ManualClock()
    runner = DeviceRunner(lambda now: _make(profile_name, now), clock)
    port = InProcessTransport("bench://")
    runner.attach_transport("main", port, FAST)
    port.attach(HOST)
    clock.advance(2.0)

    def exchange() -> None:
        port.send(request)
        out = port.take(len(reply) + 1)
        if out != reply:
            raise BenchError(f"{profile_name} runner: {request!r} answered {out!r}, expected {reply!r}")

    def between() -> None:
        clock.advance(SPACING_S)

    return exchange, between


def _timed(exchange: Exchange, samples: int) -> tuple[float, float]:
    step, between = exchange
    for _ in range(WARMUP):
        step()
        between()
    times = []
    clock = time.perf_counter
    for _ in range(samples):
        start = clock()
        step()
        times.append((clock() - start) * 1e6)
        between()
    return p50_p99(times)
