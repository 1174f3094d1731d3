"""The runner's direct step for unpaced host bytes (`DeviceRunner.host_data`) is an optimisation only:
whatever a host does, the bytes it gets, their instants, the device's state and the events are the
same as when every byte takes the round through the input pacer and a whole `pump`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from hypothesis import given
from hypothesis import strategies as st

from emulator.device import DeviceServices, LineSettings
from emulator.hosting import mismatch
from emulator.hosting.clock import ManualClock
from emulator.hosting.port import Port
from emulator.hosting.runner import DeviceRunner
from emulator.profiles.profile import load_profile
from emulator.profiles.registry import family
from emulator.wire_time import FAST, REALISTIC
from tests.support.fuzz import fuzz_settings
from tests.support.memory_transport import MemoryTransport
from tests.support.probe_device import PROBE_PROFILE as PROBE
from tests.support.probe_device import ProbeDevice
from tests.unit.mp285.test_mp285_fuzz import VALID
from tests.unit.ms2000.test_fuzz import lines as ms2000_lines

FUZZ = fuzz_settings(150)
HOST = LineSettings(9600, None, None, 1, False, False)


class PumpedRunner(DeviceRunner):
    """The reference: host bytes always queued on the input pacer, then one whole step."""

    def host_data(self, ch: Port, data: bytes) -> None:
        ch.from_host.push(self.clock.now(), data)
        if ch.pending_mismatch:
            mismatch.report(ch, self.device)
        self.pump()


class LateClock(ManualClock):
    """A manual clock that can also move without telling the runner, as a real clock does while
    the runner's timer has not fired yet (a late wakeup, or bytes arriving first)."""

    def drift(self, seconds: float) -> None:
        self._now += seconds


@dataclass
class Run:
    clock: LateClock
    runner: DeviceRunner
    port: MemoryTransport
    received: list[tuple[float, bytes]]
    events: list[tuple[str, dict[str, Any]]]


class TimedTransport(MemoryTransport):
    """Remembers the device time of every write (what the host sees, and when)."""

    def __init__(self, clock: ManualClock) -> None:
        super().__init__()
        self.clock = clock
        self.timed: list[tuple[float, bytes]] = []

    def write(self, data: bytes) -> int:
        self.timed.append((self.clock.now(), bytes(data)))
        return super().write(data)


def start(runner_type: type[DeviceRunner], profile_path: str, timing: str) -> Run:
    clock = LateClock()
    profile = load_profile(profile_path)
    registered = family(profile.family)
    assert registered is not None
    factory = registered.factory
    events: list[tuple[str, dict[str, Any]]] = []
    runner = runner_type(
        lambda now: factory("dut", profile, now, DeviceServices()),
        clock,
        on_event=lambda name, ev: events.append((name, ev)),
    )
    port = TimedTransport(clock)
    runner.attach_transport("main", port, timing)
    port.attach(HOST)
    clock.advance(2.0)  # past any power-up silence
    return Run(clock, runner, port, port.timed, events)


DELAYS = [0.0, 0.0001, 0.003, 0.05, 0.4]
OTHER_HOST = LineSettings(19200, None, None, 2, False, False)
# a script step: bytes from the host, device time passing (noticed, or not yet), the host's
# settings, or a fault injected
PROBE_LINES = [b"E hi\r", b"D 5 later\r", b"D 0 now\r", b"B 3\r"]
steps = st.one_of(
    st.tuples(st.just("send"), st.binary(min_size=1, max_size=24)),
    st.tuples(st.just("send"), st.sampled_from(PROBE_LINES)),
    st.tuples(st.just("wait"), st.sampled_from(DELAYS)),
    st.tuples(st.just("drift"), st.sampled_from(DELAYS)),
    st.tuples(st.just("host"), st.sampled_from([HOST, OTHER_HOST])),
    st.tuples(
        st.just("fault"),
        st.sampled_from(
            [
                ("drop", {}),
                ("corrupt", {"count": 2}),
                ("latency", {"ms": 3}),
                ("hang", {"seconds": 0.01}),
                ("clear", {}),
            ]
        ),
    ),
)


def play(run: Run, script: list[tuple[str, Any]]) -> dict[str, Any]:
    assert run.port.sink is not None
    for kind, value in script:
        if kind == "send":
            run.port.send(value)
        elif kind == "wait":
            run.clock.advance(value)
        elif kind == "drift":
            run.clock.drift(value)
        elif kind == "host":
            run.port.sink.host_line(value)
        else:
            fault, params = value
            run.runner.inject("main", fault, params)
    run.clock.advance(2.0)
    now = run.runner.pump()
    ch = run.runner.channels["main"]
    return {
        "host got": run.received,
        "device": run.runner.device.snapshot(now),
        "events": run.events,
        "port": (ch.stats.describe(), ch.faults.describe(), ch.reported_mismatch, run.port.resumes),
    }


def same_either_way(profile_path: str, timing: str, script: list[tuple[str, Any]]) -> None:
    direct = play(start(DeviceRunner, profile_path, timing), script)
    pumped = play(start(PumpedRunner, profile_path, timing), script)
    assert direct == pumped


@FUZZ
@given(st.lists(steps, max_size=30))
def test_probe_bytes_faults_and_timers_same_either_way(script: list) -> None:
    same_either_way(PROBE, FAST, script)


ms2000_sends = ms2000_lines.map(lambda line: ("send", line.encode("latin-1") + b"\r"))


@FUZZ
@given(st.lists(st.one_of(ms2000_sends, steps), max_size=20))
def test_ms2000_same_either_way(script: list) -> None:
    same_either_way("ms2000", FAST, script)


mp285_sends = st.sampled_from(VALID).map(lambda frame: ("send", frame))


@FUZZ
@given(st.lists(st.one_of(mp285_sends, steps), max_size=30))
def test_mp285_same_either_way(script: list) -> None:
    same_either_way("mp285", FAST, script)


@FUZZ
@given(st.lists(steps, max_size=20))
def test_realistic_timing_same_either_way(script: list) -> None:
    """Paced input never takes the direct step; an unpaced line (MP-285 `pace_line: false`) may."""
    same_either_way("mp285", REALISTIC, script)
    same_either_way(PROBE, REALISTIC, script)


def test_the_direct_step_is_taken_for_unpaced_bytes_with_nothing_ahead() -> None:
    run = start(DeviceRunner, PROBE, FAST)
    pacer = run.runner.channels["main"].from_host
    run.port.send(b"E hi\r")
    assert run.port.take() == b"hi\r" and pacer.wire_free == float("-inf")  # never queued
    run.runner.inject("main", "hang", {"seconds": 0.01})
    run.port.send(b"E lost\r")
    assert run.port.take() == b"" and pacer.wire_free == run.clock.now()  # a hung device: queued


def test_a_fault_expiry_due_runs_before_the_bytes_arrive() -> None:
    """Bytes that arrive before the runner's timer fired for a due expiry still come after it."""
    run = start(DeviceRunner, PROBE, FAST)
    device = run.runner.device
    assert isinstance(device, ProbeDevice)
    seen_at_expiry: list[int] = []
    run.runner.after(0.01, lambda: seen_at_expiry.append(len(device.received)))
    run.clock.drift(0.02)
    run.port.send(b"E hi\r")
    assert seen_at_expiry == [0] and len(device.received) == 1
