"""The runner's step as its parts see it: the device's line settings are read once per step (and once
more only after a change between steps), a change made between steps paces that very step, and the
direct step's predicate (`Port.express`) follows each of its inputs."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from emulator.device import DeviceServices, LineSettings
from emulator.hosting.clock import ManualClock
from emulator.hosting.runner import DeviceRunner
from emulator.profiles.profile import load_profile
from emulator.wire_time import FAST, REALISTIC
from tests.support.memory_transport import MemoryTransport
from tests.support.probe_device import PROBE_PROFILE as PROBE
from tests.support.probe_device import ProbeDevice

HOST = LineSettings(9600, None, None, 1, False, False)


class CountingProbe(ProbeDevice):
    """The probe, counting how often its host asks for its line settings, with a `baud` input that
    changes them and answers at once (as a controller's baud command does)."""

    reads = 0
    baud: int | None = None

    def line_settings(self, channel: str = "main") -> LineSettings:
        CountingProbe.reads += 1
        own = super().line_settings(channel)
        return own if self.baud is None else replace(own, baud=self.baud)

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        if name == "baud":
            self.baud = int(params["baud"])
            self._reply(now, b"ok\r", "baud")
            return True
        return super().control_input(name, params, now)


@dataclass
class Host:
    clock: ManualClock
    runner: DeviceRunner
    port: MemoryTransport


def make(timing: str) -> Host:
    clock = ManualClock()
    profile = load_profile(PROBE)
    runner = DeviceRunner(lambda now: CountingProbe("probe-0", profile, now, DeviceServices()), clock)
    port = MemoryTransport()
    runner.attach_transport("main", port, timing)
    port.attach(HOST)
    return Host(clock, runner, port)


def reads_during(action: Any) -> int:
    before = CountingProbe.reads
    action()
    return CountingProbe.reads - before


def test_the_device_settings_are_read_once_per_step() -> None:
    h = make(FAST)
    assert reads_during(lambda: h.port.send(b"E hi\r")) == 1  # the direct step
    assert h.port.take() == b"hi\r"
    assert reads_during(lambda: h.clock.advance(0.01)) == 1  # a pumped step
    # a host's new settings: pacing follows before the step, the step's own changes after it
    sink = h.port.sink
    assert sink is not None
    assert reads_during(lambda: sink.host_line(HOST)) == 2


def test_a_settings_change_between_steps_paces_that_step() -> None:
    """A control input that changes the device's baud and answers at once: the answer leaves at the
    new baud (1200: 8.3 ms a character), not at the old one (9600: 1.04 ms)."""
    h = make(REALISTIC)
    h.clock.advance(1.0)
    h.runner.call(lambda now: h.runner.device.control_input("baud", {"baud": 1200}, now))
    h.clock.advance(3 * 10 / 9600)
    assert h.port.take() == b""
    h.clock.advance(3 * 10 / 1200 - 3 * 10 / 9600)
    assert h.port.take() == b"ok\r"


def test_the_direct_step_follows_pacing_traffic_and_hang() -> None:
    h = make(FAST)
    ch = h.runner.channels["main"]
    assert ch.express
    h.runner.inject("main", "hang", {"seconds": 0.01})
    assert not ch.express
    h.clock.advance(0.01)  # the hang expires
    assert ch.express
    h.runner.watch_traffic(lambda record: None)
    assert not ch.express
    h.runner.watch_traffic(None)
    assert ch.express
    assert not make(REALISTIC).runner.channels["main"].express
