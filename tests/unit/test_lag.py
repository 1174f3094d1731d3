"""A device with more work than the CPU can do falls behind the clock in bounded steps and reaches
the same outcome later (emulator/hosting/lag.py; issue "Hardening, round two", item 1).

The work budget is measured on a fake timer that advances one unit per reading, so a step's slice is
a fixed number of model events and every run is deterministic."""

from __future__ import annotations

import asyncio
import json
import logging
from pathlib import Path
from typing import Any

import pytest

from emulator.device import DeviceServices, LineSettings
from emulator.hosting.clock import ManualClock, ScaledClock
from emulator.hosting.control import ControlServer
from emulator.hosting.lag import DeviceClock, WorkBudget
from emulator.hosting.runner import DeviceRunner
from emulator.profiles.profile import load_profile
from emulator.profiles.registry import family
from emulator.wire_time import FAST
from tests.support.memory_transport import MemoryTransport

HOST = LineSettings(9600, None, None, 1, False, False)
#: a SEQUENCER block stepping every millisecond: one model event per ms of device time
PROGRAM = {"blocks": [{"start": [12], "repeat": [12], "delay_ms": 1, "repetitions": 3000}]}


class Ticks:
    """A work timer that advances a millisecond per reading: `SLICE` allows 50 readings."""

    def __init__(self) -> None:
        self.readings = 0

    def __call__(self) -> float:
        self.readings += 1
        return self.readings / 1000


SLICE = 0.05


def _runner(
    clock: ManualClock, budget: WorkBudget | None
) -> tuple[DeviceRunner, MemoryTransport, list[dict]]:
    profile = load_profile("ms2000-seq")
    events: list[dict[str, Any]] = []
    runner = DeviceRunner(
        lambda now: family("ms2000").factory("seq", profile, now, DeviceServices()),
        clock,
        on_event=lambda _name, event: events.append(event),
        budget=budget,
    )
    port = MemoryTransport()
    runner.attach_transport("main", port, FAST)
    port.attach(HOST)
    runner.call(lambda now: runner.device.control_input("sequencer", PROGRAM, now))
    port.send(b"ARM X\r")
    assert port.take() == b":A\r\n"
    events.clear()
    return runner, port, events


def test_device_clock_is_the_shared_clock_until_the_device_falls_behind() -> None:
    shared = ManualClock(10.0)
    clock = DeviceClock(shared)
    assert clock.now() == 10.0 and clock.behind == 0.0
    clock.set_behind(4.0)
    shared.advance(1.0)
    assert clock.now() == 7.0
    clock.set_behind(-1.0)  # never ahead of the shared clock
    assert clock.behind == 0.0 and clock.now() == 11.0


def test_a_step_does_at_most_its_budget_of_model_work_then_falls_behind() -> None:
    """Today one step ran every event due, however many: 3 s of a 1 ms sequencer at once."""
    clock = ManualClock()
    ticks = Ticks()
    runner, _, events = _runner(clock, WorkBudget(seconds=SLICE, timer=ticks))
    clock.advance(3.0)  # the clock's listener pumps once
    instants = sorted({event["t"] for event in events})
    assert 0 < len(instants) <= 51, len(instants)  # one step per budget reading, the last one over
    assert runner.clock.behind == pytest.approx(3.0 - instants[-1])
    assert runner.lag.lagging


def test_behind_the_clock_the_device_reaches_the_same_outcome_later() -> None:
    """Every event at the same device instant as a device that kept up, then caught up."""
    reference_clock = ManualClock()
    reference, _, expected = _runner(reference_clock, None)
    reference_clock.advance(3.0)

    clock = ManualClock()
    runner, _, events = _runner(clock, WorkBudget(seconds=SLICE, timer=Ticks()))
    clock.advance(3.0)
    steps = 1
    while runner.clock.behind:
        runner.pump()
        steps += 1
    assert steps > 10
    assert events == expected and len(expected) > 1000
    assert runner.device.snapshot(3.0) == reference.device.snapshot(3.0)


def test_a_host_behind_the_clock_is_answered_in_order_with_the_device_events() -> None:
    clock = ManualClock()
    runner, port, _ = _runner(clock, WorkBudget(seconds=SLICE, timer=Ticks()))
    clock.advance(3.0)
    assert runner.clock.behind > 1.0
    port.send(b"W X\r")  # stamped with the device's own time: heard in the next slice
    assert port.take() == b":A 0\r\n"
    assert runner.clock.behind > 1.0  # answered long before the device caught up


def test_each_episode_is_logged_once(caplog: pytest.LogCaptureFixture) -> None:
    clock = ManualClock()
    ticks = Ticks()
    runner, _, _ = _runner(clock, WorkBudget(seconds=SLICE, timer=ticks))
    with caplog.at_level(logging.INFO, logger="stage_emu.runner"):
        clock.advance(3.0)
        while runner.clock.behind:
            runner.pump()
        ticks.readings += 10_000  # ten seconds pass with the device keeping up: the episode ends
        clock.advance(0.0005)
        clock.advance(3.0)  # a second episode
        while runner.clock.behind:
            runner.pump()
    lines = [r.getMessage() for r in caplog.records]
    assert sum("cannot keep up with the clock" in line for line in lines) == 2, lines
    assert sum("keeping up with the clock again" in line for line in lines) == 1, lines
    assert runner.lag.episodes == 2


def test_without_a_budget_a_step_runs_every_event_due() -> None:
    """Hosts that own their thread (the in-process URL, unit tests) keep the unbounded step."""
    clock = ManualClock()
    runner, _, events = _runner(clock, None)
    clock.advance(3.0)
    assert runner.clock.behind == 0.0 and len(events) > 1000


def test_a_clock_step_is_answered_once_every_device_has_run_the_stepped_time(tmp_path: Path) -> None:
    """`ctl clock --step` on a paused clock: a device with more work in the step than a slice runs
    it over several loop turns, and the reply waits for that, so a host asking the device something
    after the step sees the stepped state (conformance `advance`, TV-163)."""
    path = tmp_path / "c.sock"

    async def scenario() -> None:
        clock = ScaledClock()
        clock.pause()
        profile = load_profile("ms2000-seq")
        runner = DeviceRunner(
            lambda now: family("ms2000").factory("seq", profile, now, DeviceServices()),
            clock,
            loop=asyncio.get_running_loop(),
            budget=WorkBudget(seconds=SLICE, timer=Ticks()),
        )
        port = MemoryTransport()
        runner.attach_transport("main", port, FAST)
        port.attach(HOST)
        runner.call(lambda now: runner.device.control_input("sequencer", PROGRAM, now))
        port.send(b"ARM X\r")
        server = ControlServer(path, {"seq": runner}, clock)
        await server.start()
        reader, writer = await asyncio.open_unix_connection(str(path))
        start = runner.device.now
        writer.write(b'{"op": "step", "seconds": 3}\n')
        reply = json.loads(await reader.readline())
        assert reply["ok"] and reply["result"]["now"] == pytest.approx(start + 3.0)
        assert runner.lag.episodes == 1, "the step took several slices"
        assert runner.device.now == pytest.approx(start + 3.0) and runner.clock.behind == 0.0
        writer.close()
        await server.stop()
        runner.close()

    asyncio.run(scenario())
