"""Non-volatile memory, reset and power (MS-110…MS-113, MS-111) on the model: emulator restarts, the
NvStore file format, corrupt files, failing disks and unusable stored values. The vectors TV-105…TV-110
run in tests/conformance/ms2000."""

from __future__ import annotations

import errno
import json
import logging
import os
from pathlib import Path

import pytest

from emulator.device import ControlError, DeviceServices, LineSettings
from emulator.devices.ms2000.model import Ms2000Device
from emulator.devices.ms2000.power import POSITION_SAVE_DELAY_S
from emulator.hosting.clock import ManualClock
from emulator.hosting.runner import DeviceRunner
from emulator.storage import nvstore
from emulator.storage.nvstore import NvStore
from tests.support.memory_transport import MemoryTransport
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


@pytest.fixture
def stored(tmp_path: Path) -> Harness:
    return Harness(state_dir=tmp_path)


def test_saved_settings_come_back_at_power_cycle_without_state_dir_ms111(ms: Harness) -> None:
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


def test_reset_restores_saved_settings_keeps_limits_in_place_ms112(ms: Harness) -> None:
    ms.cmd("M X=10000")
    ms.idle()
    ms.cmd("S X=1")
    ms.cmd("VB Z=2")
    ms.cmd("~")
    assert ms.cmd("S X?") == b":A X=5.145600\r\n"
    assert ms.cmd("W X") == b":A 0\r\n"
    assert ms.cmd("SU X?") == b":A X=109.000\r\n"


def test_restart_after_kill_keeps_position_ms111(stored: Harness) -> None:
    stored.cmd("M X=1000")
    stored.idle()
    stored.wait(POSITION_SAVE_DELAY_S)
    stored.restart()  # no power-off: as after kill -9
    assert stored.cmd("W X") == b":A 1000\r\n"
    assert stored.get("axes")["X"]["machine_counts"] == 4540


def _saved_x(state_dir: Path) -> float | None:
    files = list(state_dir.glob("*.json"))
    if not files:
        return None
    positions = json.loads(files[0].read_text()).get("positions") or {}
    return positions.get("X")


def test_positions_are_saved_once_the_stage_has_rested_ms111(tmp_path: Path) -> None:
    """A host moving in a loop costs no disk write per move: the positions are written once the
    stage has rested `POSITION_SAVE_DELAY_S`, with the latest position."""
    stored = Harness(state_dir=tmp_path)
    for target in (100, 200, 300):
        stored.cmd(f"M X={target}")
        stored.idle()
        stored.wait(POSITION_SAVE_DELAY_S / 4)
    assert _saved_x(tmp_path) in (None, 0.0)  # nothing at rest long enough yet
    stored.wait(POSITION_SAVE_DELAY_S)
    assert _saved_x(tmp_path) == pytest.approx(0.03, abs=1e-5)  # 300 tenths of a µm, in mm


def test_shutdown_saves_positions_not_yet_rested_long_enough_ms111(stored: Harness) -> None:
    """A daemon that stops (SIGTERM) right after a move still restarts at the new position: its
    runner's `close` calls `shut_down`, which saves what the waiting check would have saved."""
    stored.cmd("M X=500")
    stored.idle()
    stored.dev.shut_down(stored.now)
    stored.restart()
    assert stored.cmd("W X") == b":A 500\r\n"


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


def test_store_that_is_not_utf8_is_set_aside(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """A store of arbitrary bytes is corrupt like bad JSON: set aside, never a crash (MS-111)."""
    (tmp_path / "ms2000-0001.json").write_bytes(b"\xff\xfe\x00{")
    with caplog.at_level(logging.WARNING):
        h = Harness(state_dir=tmp_path)
    assert h.cmd("S X?") == b":A X=5.145600\r\n"
    assert len(list(tmp_path.glob("ms2000-0001.json.corrupt-*"))) == 1


def test_failed_ss_z_still_acks_and_is_flagged_until_a_save_works_ms111(
    stored: Harness, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """A full disk loses `SS Z` silently for the serial host, as on a real controller, but the
    control channel sees it: an event, the `storage_error` flag (`ctl list`) and a log line."""

    def disk_full(fd: int) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    path = tmp_path / "ms2000-0001.json"
    assert stored.cmd("S X=3.3") == ACK
    monkeypatch.setattr(nvstore.os, "fsync", disk_full)
    with caplog.at_level(logging.ERROR):
        assert stored.cmd("SS Z") == ACK
    (event,) = stored.take_events("storage_error")
    assert event == {
        "ev": "storage_error",
        "t": stored.t,
        "op": "save",
        "path": str(path),
        "error": "No space left on device",
    }
    assert stored.dev.storage_error == f"cannot save {path}: No space left on device"
    assert f"cannot save {path}" in caplog.text
    assert not path.exists() and os.listdir(tmp_path) == [".ms2000-0001.json.lock"]  # the owner's lock
    stored.input("power_cycle")  # the controller works on from its in-memory flash
    assert stored.cmd("S X?") == b":A X=3.300000\r\n"
    monkeypatch.undo()
    assert stored.cmd("SS Z") == ACK
    assert stored.dev.storage_error is None
    assert stored.take_events("storage_error")  # those of the power cycle's position save
    stored.restart()
    assert stored.cmd("S X?") == b":A X=3.300000\r\n"


def test_unreadable_store_is_flagged_and_starts_from_factory_ms111(tmp_path: Path) -> None:
    (tmp_path / "ms2000-0001.json").mkdir()
    h = Harness(state_dir=tmp_path)
    assert h.cmd("S X?") == b":A X=5.145600\r\n"
    assert (h.dev.storage_error or "").startswith(f"cannot load {tmp_path / 'ms2000-0001.json'}: ")
    assert [e["op"] for e in h.take_events("storage_error")] == ["load"]


def test_reset_whose_erase_fails_is_refused_and_keeps_the_device_ms111(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The host's factory reset erases the flash first; when that fails the runner keeps the old
    model and its saved settings, and the control request fails (`ctl reset` exits 1)."""
    profile = Harness().profile
    runner = DeviceRunner(
        lambda now: Ms2000Device("dut", profile, now, DeviceServices(tmp_path)), ManualClock()
    )
    port = MemoryTransport()
    runner.attach_transport("main", port, "fast")
    port.attach(LineSettings(baud=9600, stop_bits=1))
    port.send(b"S X=3.3\rSS Z\rS X=1\r")
    assert port.take() == ACK * 3
    path = tmp_path / "ms2000-0001.json"
    before = path.read_bytes()
    old = runner.device

    def read_only(self: Path, missing_ok: bool = False) -> None:
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(self))

    monkeypatch.setattr(Path, "unlink", read_only)
    with pytest.raises(
        ControlError, match=f"^dut: factory reset refused, saved settings kept: cannot erase {path}"
    ):
        runner.reset()
    monkeypatch.undo()
    assert runner.device is old
    assert old.storage_error == f"cannot erase {path}: Permission denied"
    port.send(b"S X?\r")
    assert port.take() == b":A X=1.000000\r\n", "the running model is untouched, unsaved changes included"
    assert path.read_bytes() == before
    runner.reset()
    assert runner.device is not old and not path.exists()


def test_unusable_stored_values_are_logged_once_per_key_ms111(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """Each stored value that keeps its factory value is named in one warning per load, with its
    key path and a short repr; a software reset (`~`) restores the same values without repeating."""
    Harness(state_dir=tmp_path).cmd("SS Z")
    path = tmp_path / "ms2000-0001.json"
    data = json.loads(path.read_text())
    data["saved"]["axes"]["X"]["speed"] = "fast"
    data["saved"]["axes"]["Y"]["counts_per_mm"] = 0
    data["saved"]["axes"]["Z"]["future_setting"] = 1  # another version's key: ignored, not reported
    data["saved"]["card"]["user_string"] = "x" * 100
    data["saved"]["modules"]["LED DIMMER"]["X"] = "bright"
    data["auto"] = {"axes": "none", "card": {"bca": {"Y": [1]}}}
    data["positions"] = {"X": float("nan")}
    data["physical"] = {"Z": "far"}
    path.write_text(json.dumps(data))
    with caplog.at_level(logging.WARNING, logger="stage_emu.device.dut"):
        h = Harness(state_dir=tmp_path)
        assert h.cmd("~") == ACK
        assert h.cmd("~") == ACK
    factory = "cannot be used; keeping the factory value"
    assert sorted(r.getMessage() for r in caplog.records) == sorted(
        [
            f"dut: stored saved.axes.X.speed = 'fast' {factory}",
            f"dut: stored saved.axes.Y.counts_per_mm = 0 {factory}",
            f"dut: stored saved.card.user_string = '{'x' * 36}... {factory}",
            f"dut: stored saved.modules.LED DIMMER.X = 'bright' {factory}",
            f"dut: stored auto.axes = 'none' {factory}",
            f"dut: stored auto.card.bca.Y = [1] {factory}",
            f"dut: stored positions.X = nan {factory}",
            f"dut: stored physical.Z = 'far' {factory}",
        ]
    )
    assert h.cmd("S X?") == b":A X=5.145600\r\n"


@pytest.mark.parametrize(
    "bad",
    [
        {
            "saved": {
                "axes": [1],
                "card": "x",
                "modules": {"INO_INT": [1], "RING BUFFER": "x", "LED DIMMER": 5},
            }
        },
        {"saved": {"axes": {"X": {"speed": None, "accel_ms": 0, "counts_per_mm": float("nan")}}}},
        {"saved": {"axes": {"X": {"rename": "abc", "unit_multiplier": 0}, "Y": {"rename": 1000}}}},
        {"saved": {"card": {"vb_decimals": 400, "rt_report_ms": 0, "js_fast": 0, "user_string": "é€"}}},
        {"auto": {"axes": {"X": {"soft_lower": None, "aa": "1"}}, "card": {"bca": {"Y": [1], "Q": 2}}}},
        {"positions": {"X": float("nan"), "Y": True}, "physical": {"X": float("inf")}},
    ],
)
def test_unusable_stored_values_keep_factory_values_ms111(tmp_path: Path, bad: dict) -> None:
    """Valid JSON holding values of the wrong type or that the model cannot use (hand-edited or
    foreign stores) are ignored field by field; power-up and every later command still work."""
    first = Harness(state_dir=tmp_path)
    first.cmd("SS Z")
    path = tmp_path / "ms2000-0001.json"
    data = json.loads(path.read_text())
    for section, value in bad.items():
        data[section] = {**data.get(section, {}), **value} if isinstance(value, dict) else value
    path.write_text(json.dumps(data))
    h = Harness(state_dir=tmp_path)
    assert h.cmd("S X?") == b":A X=5.145600\r\n"
    assert h.cmd("M X=1000 Y=1000") == ACK
    h.idle()
    assert h.cmd("W X Y") == b":A 1000 1000\r\n"
    assert h.cmd("BU Y?") == b"\r\n"
    h.input("wheel", counts=10)
    h.input("button", name="at", ms=1500)
    h.wait(2.0)
    assert h.cmd("/") == b"N\r\n"


def test_reset_mid_blocking_command_runs_waiting_lines_ms112_ms13(ms: Harness) -> None:
    """0xFF 'R' cancels a pending AZ silently; lines queued behind it still run, in order."""
    assert ms.send(b"AZ X\rV\r\xffR") == b":A Version: USB-9.2k \r\n"
    assert ms.cmd("W X") == b":A 0\r\n"


def test_savepos_bare_silences_queued_lines_too_ms113(ms: Harness) -> None:
    assert ms.send(b"AZ X\rSP\rV\r") == b""
    ms.wait(1.0)
    assert ms.output() == ACK + ACK
    assert ms.get("mode") == "silent"


def test_trajectory_buffer_is_volatile_ms111_ms112(ms: Harness) -> None:
    ms.cmd("M X=1000")
    ms.idle()
    assert ms.cmd("DU") != ACK
    assert ms.cmd("~") == ACK
    assert ms.cmd("DU") == ACK
    ms.cmd("M X=1000")
    ms.idle()
    ms.input("power_cycle")
    assert ms.cmd("DU") == ACK


def test_corrupt_stores_set_aside_in_the_same_second_are_all_kept(tmp_path: Path) -> None:
    """Each corrupt file is kept for inspection, however quickly they follow one another (MS-111)."""
    for _ in range(3):
        (tmp_path / "ms2000-0001.json").write_text("{not json")
        Harness(state_dir=tmp_path)
    assert len(list(tmp_path.glob("ms2000-0001.json.corrupt-*"))) == 3
