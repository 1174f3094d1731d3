"""RING BUFFER, LED DIMMER and the module plug-in mechanism (§9.0, §9.2, §9.8) on the model, beyond
the test vectors, which run in tests/conformance/ms2000 (TV-16, TV-17, TV-139…TV-145, TV-184)."""

from __future__ import annotations

import pytest

from emulator.devices.ms2000.modules import MODULES, Module
from emulator.devices.ms2000.modules.events import MoveComplete, on
from emulator.devices.ms2000.schema import SCHEMA
from emulator.profiles.profile import ProfileError
from emulator.profiles.schema import Section
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


@pytest.fixture
def loaded(ms: Harness) -> Harness:
    """Two positions loaded, in slots 0 and 1."""
    assert ms.cmd("RM X=0") == ACK
    assert ms.cmd("LD X=1000 Y=2000") == ACK
    assert ms.cmd("LD X=3000 Y=4000") == ACK
    return ms


def test_autoplay_once_visits_to_last_slot_ms_rb_5(loaded: Harness) -> None:
    loaded.cmd("LD X=5000 Y=0")
    loaded.cmd("RM F=2 Z=1")
    loaded.cmd("RT Z=1000")
    loaded.cmd("RM")
    loaded.wait(0.9)
    assert loaded.cmd("W X Y") == b":A 3000 4000\r\n"
    loaded.wait(1.0)
    assert loaded.cmd("W X Y") == b":A 5000 0\r\n"
    assert loaded.cmd("RM F? Z?") == b":A Z=0 F=2\r\n"
    loaded.wait(2.0)
    assert loaded.cmd("W X") == b":A 5000\r\n"


def test_at_button_is_next_trigger_ms_rb_5(loaded: Harness) -> None:
    loaded.input("button", name="at", ms=100)
    loaded.wait(0.2)
    loaded.idle()
    assert loaded.cmd("W X Y") == b":A 1000 2000\r\n"
    assert loaded.cmd("BE F=6") == ACK
    assert loaded.cmd("RM X?") == b":A X=0\r\n"


def test_load_errors_ms_rb_2(ms: Harness) -> None:
    assert ms.cmd("LD") == b":N-3\r\n"
    assert ms.cmd("LD Q=1") == b":N-2\r\n"
    assert ms.cmd("LD X? Y?") == b":A X=0 Y=0\r\n"
    assert ms.cmd("RM X=1") == b":N-4\r\n"


def test_ring_buffer_observable_and_lcd(loaded: Harness) -> None:
    state = loaded.get("ring_buffer")
    assert state["count"] == 2 and state["slots"][1] == {"X": 3000.0, "Y": 4000.0}
    assert loaded.get("lcd")[1].startswith("RB 0/2")


def test_led_out0_level_and_events_ms_led_1(ms: Harness) -> None:
    ms.cmd("TTL Y=9")
    assert ms.get("ttl_out0") == 0
    ms.cmd("LED X=20")
    assert ms.get("ttl_out0") == 1
    assert [e["level"] for e in ms.take_events("ttl_out0")] == [1]
    assert ms.get("led") == {"x": 20, "y": 0, "z": 0, "f": 0}
    assert ms.cmd("LED T?") == b":N-2\r\n"


def test_extra_channels_take_an_intensity_ms_led_1(ms: Harness) -> None:
    """MS-LED-1: `Y`, `Z`, `F` take 0…100 like `X` (Micro-Manager's ASIStage LED device opens a
    channel with `LED Y=20`, closes it with `LED Y=0`); the value reads back; 101 is `:N-4`."""
    assert ms.cmd("LED Y=20") == ACK
    assert ms.cmd("LED Z=100 F=1") == ACK
    assert ms.cmd("LED Y? Z? F?") == b"Y=20 Z=100 F=1 :A\r\n"
    assert ms.get("led") == {"x": 0, "y": 20, "z": 100, "f": 1}
    assert ms.cmd("LED Y=0") == ACK
    assert ms.cmd("LED Y?") == b"Y=0 :A\r\n"
    assert ms.cmd("LED Z=101") == b":N-4\r\n"
    assert ms.cmd("LED Z?") == b"Z=100 :A\r\n"


@pytest.mark.parametrize("value", ["-1", "101", "abc", "54.5"])
def test_extra_channels_check_values_as_x_does_ms_led_1(ms: Harness, value: str) -> None:
    """MS-LED-1: every channel answers a bad or fractional value as `X` does."""
    x_reply, x_value = ms.cmd(f"LED X={value}"), ms.cmd("LED X?")[1:]
    for letter in "YZF":
        assert (ms.cmd(f"LED {letter}={value}"), ms.cmd(f"LED {letter}?")[1:]) == (x_reply, x_value), letter


def test_extra_channels_saved_with_ss_z_ms_led_1(ms: Harness) -> None:
    """MS-LED-1: the intensities survive a power cycle after `SS Z`, as the duty does."""
    assert ms.cmd("LED X=30 Y=20 Z=5 F=100") == ACK
    assert ms.cmd("SS Z") == ACK
    ms.input("power_cycle")
    assert ms.cmd("LED X? Y? Z? F?") == b"X=30 Y=20 Z=5 F=100 :A\r\n"


def test_trailing_value_out_of_range_ignored_ms_led_3(ms: Harness) -> None:
    ms.cmd("LED X=5")
    assert ms.cmd("TTL Y=9 500") == ACK
    assert ms.cmd("LED X?") == b"X=5 :A\r\n"


def test_plugins_registered_and_schema_fields() -> None:
    assert {"RING BUFFER", "LED DIMMER", "INO_INT"} <= set(MODULES)
    config = Section(SCHEMA).check({}, ())
    assert (config.ring_buffer_size, config.knobs.ttl_pwm_trailing_value) == (50, "apply")


def test_version_gating_is_no_knob_ms34() -> None:
    """MS-34: features are never gated by the version string, so no profile key pretends to turn
    that on: a profile that still sets `gate_features_by_version` meets the unknown-key error."""
    with pytest.raises(ProfileError, match=r"knobs\.gate_features_by_version: unknown key"):
        Harness(overrides={"knobs": {"gate_features_by_version": False}})


def test_unknown_module_in_profile_is_refused() -> None:
    with pytest.raises(ProfileError, match="not an emulated module"):
        Harness(overrides={"modules": ["LL COMMANDS", "WARP DRIVE"]})


def test_without_ino_int_only_mode_0_ms90(make: type[Harness]) -> None:
    h = make(overrides={"modules": ["LL COMMANDS", "RING BUFFER"]})
    assert h.cmd("TTL X=1") == b":N-4\r\n"
    assert h.cmd("ZS X?") == b":N-1\r\n"
    assert h.cmd("TTL X=0") == ACK


def test_autoplay_with_zero_delay_steps_each_servo_period_ms_rb_5_ms93(loaded: Harness) -> None:
    """`RT Z=0` is in range; repeating autoplay must not spin forever at one instant."""
    assert loaded.cmd("RT Z=0") == ACK
    assert loaded.cmd("RM F=3") == ACK
    assert loaded.cmd("RM") == ACK
    loaded.wait(0.1)
    assert loaded.cmd("RM F?") == b":A F=131\r\n"
    assert loaded.cmd("RM") == ACK
    assert loaded.cmd("RM F?") == b":A F=3\r\n"


def test_trailing_value_rounds_like_led_x_ms_led_3(ms: Harness) -> None:
    """`TTL Y=9 n` sets `LED X=n`, so n rounds half away from zero like the LED command."""
    assert ms.cmd("TTL Y=9 54.5") == ACK
    assert ms.cmd("LED X?") == b"X=55 :A\r\n"
    assert ms.cmd("LED X=54.5") == ACK
    assert ms.cmd("LED X?") == b"X=55 :A\r\n"


def test_move_complete_hook_gets_every_landed_axis(
    make: type[Harness], monkeypatch: pytest.MonkeyPatch
) -> None:
    seen: list[list[str]] = []

    class Probe(Module):
        name = "PROBE"

        @on(MoveComplete)
        def move_complete(self, event: MoveComplete) -> None:
            seen.append(list(event.axes))

    monkeypatch.setitem(MODULES, Probe.name, Probe)
    ms = make(overrides={"modules": ["LL COMMANDS", "RING BUFFER", "INO_INT", "LED DIMMER", Probe.name]})
    ms.cmd("M X=1000 Y=50000 Z=10")
    ms.idle()
    assert len(seen) == 1 and sorted(seen[0]) == ["X", "Y", "Z"]
    assert seen[0][-1] == "Y"
