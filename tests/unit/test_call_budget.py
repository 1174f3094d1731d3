"""A regression guard for the hot path that does not time anything: the number of Python function
calls one round trip costs through the runner (host bytes in, model, reply out) on a manual clock.

A change that adds work per byte or per command shows up here as a higher count on any machine;
`make bench` measures what the count costs in time. Ceilings are today's counts plus ~15 %; lower
them when the path gets cheaper."""

from __future__ import annotations

import cProfile
import pstats

import pytest

from emulator.device import DeviceServices, LineSettings
from emulator.hosting.clock import ManualClock
from emulator.hosting.lag import WorkBudget
from emulator.hosting.runner import DeviceRunner
from emulator.profiles.profile import load_profile
from emulator.profiles.registry import family
from emulator.wire_time import FAST, REALISTIC
from tests.support.memory_transport import MemoryTransport
from tests.support.probe_device import PROBE_PROFILE as PROBE

ROUND_TRIPS = 200
CASES = {
    # name: (profile, request, reply, timing, ceiling in calls per round trip)
    # measured: before the settings caches 435, 286, 746; with them 311, 180, 439; with lines read
    # a run at a time and garbling decided per settings change 263, 171, 375; with parsed lines
    # remembered 234, 171, 346; with unpaced output sent without the pacer, resumes only for a
    # throttled port and the timer's due time found without temporaries 203, 142, 327; with unpaced
    # host bytes handed to the model directly (no input pacer, no whole pump) 184, 122, 325; with the
    # daemon's work budget (a step asks the model for its next deadline) 192, 130, 338; with the runner
    # split by job (the line settings read once per step, the direct step's predicate and the early
    # release span kept until what they depend on changes) 178, 119, 320
    "ms2000 W X Y fast": ("ms2000", b"W X Y\r", b":A 0 0\r\n", FAST, 195),
    "mp285 c fast": ("mp285", b"c\r", None, FAST, 128),
    "ms2000 W X Y realistic": ("ms2000", b"W X Y\r", b":A 0 0\r\n", REALISTIC, 355),
    # the framework alone: the test-only echo device costs a handful of calls (before the direct
    # step 103, with it 97, of which ~35 are the manual clock's own step after the reply; with the
    # work budget 108; with the runner split by job 89)
    "probe E fast": (PROBE, b"E hi\r", b"hi\r", FAST, 103),
}


def calls_per_round_trip(profile_name: str, request: bytes, reply: bytes | None, timing: str) -> float:
    clock = ManualClock()
    profile = load_profile(profile_name)
    registered = family(profile.family)
    assert registered is not None
    factory = registered.factory
    # with the daemon's work budget, so the step counted is the daemon's
    runner = DeviceRunner(
        lambda now: factory("dut", profile, now, DeviceServices()), clock, budget=WorkBudget()
    )
    port = MemoryTransport()
    runner.attach_transport("main", port, timing)
    port.attach(LineSettings(9600, None, None, 1, False, False))
    clock.advance(2.0)  # past any power-up silence

    def round_trip() -> None:
        port.send(request)
        clock.advance(0.05)  # the request's and the reply's wire time at 9600 baud
        answer = port.take()
        assert answer and (reply is None or answer == reply), answer

    round_trip()  # warm up: first use builds caches
    profiler = cProfile.Profile()
    profiler.enable()
    for _ in range(ROUND_TRIPS):
        round_trip()
    profiler.disable()
    return float(pstats.Stats(profiler).total_calls) / ROUND_TRIPS


@pytest.mark.parametrize("name", list(CASES))
def test_calls_per_round_trip_stay_under_their_ceiling(name: str) -> None:
    profile_name, request, reply, timing, ceiling = CASES[name]
    calls = calls_per_round_trip(profile_name, request, reply, timing)
    assert calls <= ceiling, f"{name}: {calls:.0f} calls per round trip, ceiling {ceiling}"
