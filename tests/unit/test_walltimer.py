"""The runner's wake-up timer (emulator/hosting/walltimer.py): a timerfd on Linux, the loop's millisecond
timer elsewhere; and the runner re-arming it when the clock's scale changes."""

from __future__ import annotations

import asyncio
import time

import pytest

from emulator.device import DeviceServices
from emulator.hosting import walltimer
from emulator.hosting.clock import ScaledClock
from emulator.hosting.runner import DeviceRunner
from emulator.hosting.walltimer import LOOP_TIMER_EARLY_S, TIMERFD_EARLY_S, LoopTimer, TimerFd, make_timer
from emulator.profiles.profile import load_profile
from emulator.profiles.registry import family
from tests.support.probe_device import PROBE_PROFILE as PROBE  # (registers the `probe` family)

#: wall seconds to a deadline 10 device seconds away at scale 1 (the re-arming test's old arming)
UNSCALED_S = 10.0


async def _fired_after(timer_kind: str, delay: float, *, rearm: float | None = None) -> tuple[float, int]:
    """Arm a timer for `delay` (then, with `rearm`, arm it again for that instead); wall seconds to
    its first callback and how many callbacks came within 50 ms after it."""
    loop = asyncio.get_running_loop()
    fired: list[float] = []
    first = asyncio.Event()

    def callback() -> None:
        fired.append(time.monotonic())
        first.set()

    timer = make_timer(loop, callback) if timer_kind == "best" else LoopTimer(loop, callback)
    try:
        start = time.monotonic()
        timer.arm(delay)
        if rearm is not None:
            timer.arm(rearm)
        await asyncio.wait_for(first.wait(), 5)
        await asyncio.sleep(0.05)  # a second callback, if any, would come now
        return fired[0] - start, len(fired)
    finally:
        timer.close()


def test_the_best_timer_on_linux_is_a_timerfd_released_a_tenth_of_a_millisecond_early() -> None:
    async def check() -> None:
        timer = make_timer(asyncio.get_running_loop(), lambda: None)
        try:
            assert isinstance(timer, TimerFd) and timer.early == TIMERFD_EARLY_S == 0.0001
        finally:
            timer.close()

    asyncio.run(check())


@pytest.mark.parametrize("kind", ["best", "loop"])
def test_a_timer_fires_once_no_earlier_than_armed(kind: str) -> None:
    waited, count = asyncio.run(_fired_after(kind, 0.02))
    assert waited >= 0.02 and count == 1


@pytest.mark.parametrize("kind", ["best", "loop"])
def test_arming_again_replaces_the_earlier_arming(kind: str) -> None:
    waited, count = asyncio.run(_fired_after(kind, 0.01, rearm=0.03))
    assert waited >= 0.03 and count == 1


@pytest.mark.parametrize("kind", ["best", "loop"])
def test_a_cancelled_timer_never_fires(kind: str) -> None:
    async def check() -> list[int]:
        loop = asyncio.get_running_loop()
        fired: list[int] = []
        timer = make_timer(loop, lambda: fired.append(1)) if kind == "best" else LoopTimer(loop, fired.append)
        timer.arm(0.005)
        timer.cancel()
        marker = asyncio.Event()
        loop.call_later(0.03, marker.set)  # well past the cancelled expiry
        await marker.wait()
        timer.close()
        return fired

    assert asyncio.run(check()) == []


def test_without_a_timerfd_the_loop_timer_is_used_with_half_a_millisecond_early(monkeypatch) -> None:
    def unavailable() -> walltimer._Libc:
        raise OSError("no timerfd here")

    monkeypatch.setattr(walltimer, "_load_libc", unavailable)

    async def check() -> None:
        timer = make_timer(asyncio.get_running_loop(), lambda: None)
        assert isinstance(timer, LoopTimer) and timer.early == LOOP_TIMER_EARLY_S

    asyncio.run(check())


def test_a_scale_change_rearms_the_runner_for_the_same_device_time() -> None:
    """A deadline armed at scale 1 is 10 wall seconds away; at scale 100 the same device instant is
    0.1 s away, and the runner must wake then, not 10 s later."""

    async def check() -> float:
        loop = asyncio.get_running_loop()
        clock = ScaledClock(1.0)
        profile = load_profile(PROBE)
        runner = DeviceRunner(
            lambda now: family("probe").factory("probe-0", profile, now, DeviceServices()), clock, loop=loop
        )
        due = clock.now() + 10.0
        reached = asyncio.Event()
        runner.after(10.0, reached.set)
        clock.set_scale(100.0)
        start = time.monotonic()
        await asyncio.wait_for(reached.wait(), UNSCALED_S)
        runner.close()
        assert clock.now() >= due
        return time.monotonic() - start

    # 0.1 s when re-armed; not re-armed, the old arming would fire after 10 s: half of that tells
    # them apart, and only a loop held for seconds could make it fail
    assert asyncio.run(check()) < UNSCALED_S / 2
