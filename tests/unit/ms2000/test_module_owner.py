"""Modules (rule 6 of the design): a firmware module is one file that registers everything it
adds, sees the controller only as a `ModuleOwner`, and is enabled by a profile. Proved with
test-only modules defined in this file: no other file of the controller or its modules changes,
not even to let one of them talk to an existing module (ARRAY) through events."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any, ClassVar

import pytest

from emulator.devices.ms2000.calls import Call, Param, Reply, run_settings, within
from emulator.devices.ms2000.modules import MODULES, Handler, Module
from emulator.devices.ms2000.modules.capabilities import ControlChannel, LcdSegment, Playback
from emulator.devices.ms2000.modules.events import ArrayArrival, Reset, RmX, on
from emulator.devices.ms2000.modules.owner import ModuleOwner
from emulator.devices.ms2000.schema import DEFAULT_MODULES
from emulator.profiles.profile import ProfileError, load_profile
from emulator.profiles.schema import Field, Int
from protocols.ms2000 import Fmt, Shape
from tests.unit.ms2000.conftest import Harness, schema_rebuilt

ACK = b":A\r\n"
PROBE = "TEST PROBE"
WATCHER = "TEST ARRAY WATCHER"


class ProbeModule(Module, ControlChannel, LcdSegment):
    """A test-only module: a command, a reply shape, a knob, an observable, an input, a `BU X` line,
    an LCD segment and an `SS Z` setting, all declared here (the capabilities it derives from say
    which of these the controller asks it for)."""

    name = PROBE
    # WRDAC belongs to DAC OUT in the command table; no emulated module implements it yet
    query_shapes: ClassVar[Mapping[str, Shape]] = {"WRDAC": Shape.AXIS_COLON_A}
    knob_fields = (Field("probe_gain", Int(1, 10), 1, "TEST", "kicks per probe_kick (TEST PROBE)"),)
    observable = "probe"
    inputs = frozenset({"probe_kick"})

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.volts = 0.0
        self.kicks = 0

    def handlers(self) -> dict[str, Handler]:
        return {"WRDAC": self.wrdac}

    def wrdac(self, call: Call) -> Reply:
        params = {"X": Param(lambda: self.volts, self._set, within(0, 10), Fmt.F6)}
        return run_settings(call, params, "X", self.controller.render(call.key), self.controller.ack())

    def _set(self, volts: float) -> None:
        self.volts = volts

    def bu_line(self) -> str:
        return f"{self.name} v1"

    def lcd_segment(self, now: float) -> str | None:
        return f"P{self.kicks}"

    def observe(self, now: float) -> Any:
        return {"volts": self.volts, "kicks": self.kicks}

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        self.kicks += int(params.get("times", 1)) * self.controller.knobs.probe_gain
        self.controller.push_event({"ev": "probe_kicked", "t": now, "kicks": self.kicks})
        return self.kicks

    def save(self) -> dict[str, Any]:
        return {"volts": self.volts}

    def restore(self, data: dict[str, Any] | None) -> None:
        volts = (data or {}).get("volts", 0.0)
        self.volts = float(volts) if isinstance(volts, int | float) else 0.0

    @on(Reset)
    def reset(self, event: Reset) -> None:
        self.kicks = 0


class ArrayWatcher(Module, ControlChannel):
    """A test-only module that talks to ARRAY through events alone: its input `watch_start` sends the
    `RmX` event RING BUFFER sends for `RM X=1`, which starts ARRAY's commanded stepping
    (MS-ARRAY-6), and it hears each cell ARRAY reaches (`ArrayArrival`, MS-ARRAY-8). It reads RING
    BUFFER's playback mode by capability (`Playback`), not by asking every module."""

    name = WATCHER
    observable = "watcher"
    inputs = frozenset({"watch_start"})

    def __init__(self, controller: ModuleOwner) -> None:
        super().__init__(controller)
        self.arrivals: list[float] = []

    def control_input(self, name: str, params: dict[str, Any], now: float) -> Any:
        self.controller.emit(RmX(now, 1))

    @on(ArrayArrival)
    def arrived(self, event: ArrayArrival) -> None:
        self.arrivals.append(event.t)

    def observe(self, now: float) -> Any:
        ring = self.controller.module(Playback)
        return {"arrivals": list(self.arrivals), "playback": ring.playback_mode() if ring else None}


@pytest.fixture
def probe_registered(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Register the modules and their schema fields, as importing their files from modules/ would."""
    monkeypatch.setitem(MODULES, PROBE, ProbeModule)
    monkeypatch.setitem(MODULES, WATCHER, ArrayWatcher)
    with schema_rebuilt():
        yield


@pytest.fixture
def probed(probe_registered: None) -> Harness:
    """A build that lists the module (a profile override: a profile YAML would list it the same way)."""
    profile = load_profile("ms2000", {"modules": [*DEFAULT_MODULES, PROBE], "knobs": {"probe_gain": 3}})
    return Harness(profile)


def test_module_command_and_reply_shape(probed: Harness) -> None:
    assert probed.cmd("WRDAC X=1.5") == ACK
    assert probed.cmd("WRDAC X?") == b"X=1.500000 :A\r\n"
    assert probed.cmd("WRDAC X=20") == b":N-4\r\n"


def test_module_command_is_absent_without_the_module_ms118(probe_registered: None) -> None:
    assert Harness().cmd("WRDAC X=1.5") == b":N-1\r\n"


def test_module_bu_x_line_in_profile_order_ms102(probed: Harness) -> None:
    lines = probed.cmd("BU X").removesuffix(b"\r\n").split(b"\r")
    assert lines[-5:] == [b"LL COMMANDS", b"RING BUFFER 50", b"INO_INT", b"LED DIMMER", b"TEST PROBE v1"]


def test_module_input_observable_event_and_lcd_segment(probed: Harness) -> None:
    names = probed.dev.control_names()
    assert "probe_kick" in names["inputs"] and "probe" in names["observables"]
    assert probed.input("probe_kick", times=2) == 6, "the module's own knob, probe_gain 3"
    assert probed.get("probe") == {"volts": 0.0, "kicks": 6}
    assert [e["kicks"] for e in probed.take_events("probe_kicked")] == [6]
    assert probed.get("lcd")[1].split()[:3] == ["RB", "0/0", "L"]
    assert "P6" in probed.get("lcd")[1].split()
    assert "probe" in probed.dev.snapshot(probed.t)


def test_module_setting_saved_by_ss_z_and_state_reset_ms111_ms112(probed: Harness) -> None:
    probed.cmd("WRDAC X=2.5")
    probed.input("probe_kick")
    assert probed.cmd("SS Z") == ACK
    probed.cmd("WRDAC X=7")
    assert probed.cmd("~") == ACK
    assert probed.get("probe") == {"volts": 2.5, "kicks": 0}
    probed.cmd("WRDAC X=7")
    probed.input("power_cycle")
    assert probed.cmd("WRDAC X?") == b"X=2.500000 :A\r\n"


def test_module_knob_is_a_validated_profile_key(probe_registered: None) -> None:
    with pytest.raises(ProfileError, match="probe_gain"):
        load_profile("ms2000", {"modules": [PROBE], "knobs": {"probe_gain": 11}})
    assert load_profile("ms2000").config.knobs.probe_gain == 1


def test_module_talks_to_an_existing_module_through_events_ms_array_6_ms_array_8(
    probe_registered: None,
) -> None:
    """The watcher starts ARRAY's stepping with an event and hears the arrival ARRAY reports: the
    same instant as ARRAY's own control event, with nothing of either module changed."""
    modules = [*load_profile("ms2000-seq").config.modules, WATCHER]
    h = Harness("ms2000-seq", {"modules": modules})
    assert h.cmd("AR X=2 Y=2 Z=1 F=1") == ACK
    assert h.cmd("RM F=3") == ACK
    h.input("watch_start")
    h.idle()
    reported = h.take_events("array_arrival")
    assert [(e["i"], e["j"]) for e in reported] == [(1, 1)]
    assert h.get("watcher") == {"arrivals": [reported[0]["t"]], "playback": 3}
    assert h.get("array")["running"] == "stepping"


def test_event_subscriptions_are_found_once_per_class() -> None:
    """A module's `@on` methods, inherited ones included, make its subscription table."""
    assert ProbeModule.subscriptions == {Reset: "reset"}
    assert ArrayWatcher.subscriptions == {ArrayArrival: "arrived"}


def test_two_handlers_of_one_event_in_a_class_are_refused() -> None:
    """One method per event class and module: a second is a mistake caught as the class is made."""
    with pytest.raises(TypeError, match="two handlers of Reset"):

        class Twice(Module):
            name = "TWICE"

            @on(Reset)
            def first(self, event: Reset) -> None: ...

            @on(Reset)
            def second(self, event: Reset) -> None: ...
