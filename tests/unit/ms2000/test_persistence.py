"""Non-volatile memory, reset and power (MS-110…MS-113, MS-111): TV-105…TV-110, emulator restarts,
the NvStore file format and corrupt files."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import pytest

from emulator.nvstore import NvStore
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


@pytest.fixture
def stored(tmp_path: Path) -> Harness:
    return Harness(state_dir=tmp_path)


def test_tv105_saved_settings_survive_restart_ms111(stored: Harness) -> None:
    assert stored.cmd("S X=3.3") == ACK
    assert stored.cmd("SS Z") == ACK
    stored.restart()
    assert stored.cmd("S X?") == b":A X=3.300000\r\n"
    assert stored.cmd("S Y=2") == ACK
    stored.input("power_cycle")
    assert stored.cmd("S Y?") == b":A Y=5.145600\r\n"


def test_tv105_without_state_dir_power_cycle_still_uses_flash_ms111(ms: Harness) -> None:
    ms.cmd("S X=3.3")
    ms.cmd("SS Z")
    ms.cmd("S X=1")
    ms.input("power_cycle")
    assert ms.cmd("S X?") == b":A X=3.300000\r\n"


def test_nothing_persists_without_state_dir(ms: Harness) -> None:
    ms.cmd("S X=3.3")
    ms.cmd("SS Z")
    ms.restart()
    assert ms.cmd("S X?") == b":A X=5.145600\r\n"


def test_tv106_soft_limits_remembered_automatically_ms111(ms: Harness) -> None:
    assert ms.cmd("SL X=-50") == ACK
    ms.input("power_cycle")
    assert ms.cmd("SL X?") == b":A X=-50.000\r\n"


def test_tv107_factory_reset_scheduled_and_cancelled_ms110_ms112(stored: Harness) -> None:
    stored.cmd("S X=3.3")
    stored.cmd("SS Z")
    assert stored.cmd("SS X") == ACK
    stored.input("power_cycle")
    assert stored.cmd("S X?") == b":A X=5.145600\r\n"
    stored.input("power_cycle")
    assert stored.cmd("S X?") == b":A X=5.145600\r\n"
    stored.cmd("S X=3.3")
    stored.cmd("SS Z")
    assert stored.cmd("SS X") == ACK
    assert stored.cmd("SS Y") == ACK
    stored.input("power_cycle")
    assert stored.cmd("S X?") == b":A X=3.300000\r\n"


def test_tv108_reset_zeroes_positions_ms112(ms: Harness) -> None:
    ms.cmd("M X=1000")
    ms.idle()
    ms.cmd("BU Z+")
    assert ms.cmd("~") == ACK
    assert ms.cmd("W X Y Z") == b":A 0 0 0\r\n"
    assert ms.cmd("BU Z?") == b":A 0\r\n"


def test_reset_restores_saved_settings_keeps_limits_in_place_ms112(ms: Harness) -> None:
    ms.cmd("M X=10000")
    ms.idle()
    ms.cmd("S X=1")
    ms.cmd("VB Z=2")
    ms.cmd("~")
    assert ms.cmd("S X?") == b":A X=5.145600\r\n"
    assert ms.cmd("W X") == b":A 0\r\n"
    assert ms.cmd("SU X?") == b":A X=109.000\r\n"


def test_tv109_positions_saved_at_power_off_unless_inhibited_ms113_ms112(ms: Harness) -> None:
    ms.cmd("M X=1000")
    ms.idle()
    ms.input("power_cycle")
    assert ms.cmd("W X") == b":A 1000\r\n"
    assert ms.cmd("SP X=1") == ACK
    assert ms.cmd("SP X?") == b":A X=1\r\n"
    ms.input("power_cycle")
    assert ms.cmd("W X") == b":A 0\r\n"
    assert ms.get("axes")["X"]["machine_counts"] == 4540


def test_tv110_savepos_bare_goes_silent_ms113_ms18(ms: Harness) -> None:
    assert ms.cmd("SP") == ACK
    assert ms.cmd("V") == b""
    assert ms.send(b"\xffB\x18\x61\x03\x3a") == b""
    ms.input("power_cycle")
    assert ms.cmd("V") == b":A Version: USB-9.2k \r\n"


def test_restart_after_kill_keeps_position_ms111(stored: Harness) -> None:
    stored.cmd("M X=1000")
    stored.idle()
    stored.restart()  # no power-off: as after kill -9
    assert stored.cmd("W X") == b":A 1000\r\n"
    assert stored.get("axes")["X"]["machine_counts"] == 4540


def test_auto_saved_items_survive_restart_ms111(stored: Harness) -> None:
    stored.cmd("SU Y=12")
    stored.cmd("AA Z=12")
    stored.cmd("BCA X=3")
    stored.cmd("CCA X=7")
    stored.restart()
    assert stored.cmd("SU Y?") == b":A Y=12.000\r\n"
    assert stored.cmd("AA Z?") == b":A Z=12\r\n"
    assert stored.cmd("BCA X?") == b":A X=3\r\n"
    assert stored.cmd("CCA X?") == b":A X=7\r\n"


def test_module_settings_saved_with_ss_z_ms111(stored: Harness) -> None:
    stored.cmd("RM Y=4 F=2")
    stored.cmd("LED X=30")
    stored.cmd("ZS X=5")
    stored.cmd("TTL Y=9")
    stored.cmd("SS Z")
    stored.restart()
    assert stored.cmd("RM Y? F?") == b":A Y=4 F=2\r\n"
    assert stored.cmd("LED X?") == b"X=30 :A\r\n"
    assert stored.cmd("ZS X?") == b":A X=5.000000\r\n"
    assert stored.get("ttl_out0_pwm") == 30


def test_other_identity_is_ignored_and_logged_ms111(tmp_path: Path) -> None:
    first = Harness(state_dir=tmp_path)
    first.cmd("S X=3.3")
    first.cmd("SS Z")
    other = Harness(overrides={"build_name": "OTHER"}, state_dir=tmp_path)
    assert other.cmd("S X?") == b":A X=5.145600\r\n"
    assert other.cmd("DU Y") == b"55\r:A\r\n"


def test_store_file_is_json_per_device_id(stored: Harness, tmp_path: Path) -> None:
    stored.cmd("SS Z")
    data = json.loads((tmp_path / "ms2000-0001.json").read_text())
    assert data["identity"] == {"build": "STD_XYZ", "version": "USB-9.2k", "axes": ["X", "Y", "Z"]}
    assert data["saved"]["axes"]["X"]["speed"] == 5.1456
    assert not list(tmp_path.glob(".*.tmp"))


def test_corrupt_store_is_set_aside(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    (tmp_path / "ms2000-0001.json").write_text("{not json")
    with caplog.at_level(logging.WARNING):
        h = Harness(state_dir=tmp_path)
    assert h.cmd("S X?") == b":A X=5.145600\r\n"
    assert "corrupt" in caplog.text
    assert len(list(tmp_path.glob("ms2000-0001.json.corrupt-*"))) == 1
    h.cmd("SS Z")
    assert json.loads((tmp_path / "ms2000-0001.json").read_text())["saved"]


def test_nvstore_non_object_and_erase(tmp_path: Path) -> None:
    (tmp_path / "a.json").write_text("[1, 2]")
    store = NvStore(tmp_path, "a")
    assert store.load() == {}
    store.save({"k": 1})
    assert NvStore(tmp_path, "a").load() == {"k": 1}
    store.erase()
    assert not (tmp_path / "a.json").exists()
    assert NvStore(tmp_path, "a").load() == {}


def test_nvstore_unsafe_names_and_memory_only(tmp_path: Path) -> None:
    store = NvStore(tmp_path, "../evil id")
    store.save({"x": 1})
    assert (tmp_path / ".._evil_id.json").exists()
    memory = NvStore(None, "m")
    memory.save({"x": 2})
    assert memory.load() == {"x": 2} and not memory.persistent


def test_forget_nonvolatile_gives_factory_device(stored: Harness) -> None:
    stored.cmd("S X=3.3")
    stored.cmd("SS Z")
    stored.dev.forget_nonvolatile()
    stored.restart()
    assert stored.cmd("S X?") == b":A X=5.145600\r\n"
