"""The controller's flash on a store the host hands in (MS-110, MS-111): the model never sees a
file; a store that writes in the background (the daemon's) holds the `SS` reply until the data is
on disk; positions are saved once the stage has come to rest (`POSITION_SAVE_DELAY_S`), never per
command."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest

from emulator.device import DeviceServices, StoreReport
from emulator.devices.ms2000.power import POSITION_SAVE_DELAY_S
from emulator.storage.nvstore import StorageError
from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"
VERSION = b":A Version: USB-9.2k \r\n"


class HeldStore:
    """In memory, persistent as far as the model knows, writing only when the test says so: the
    daemon's store with a slow disk. Survives model restarts, like a state directory."""

    persistent = True

    def __init__(self) -> None:
        self.disk: dict[str, Any] = {}
        self.waiting: list[dict[str, Any]] = []
        self.writes = 0
        self.report: StoreReport = lambda failure: None

    def open(self, device_id: str, report: StoreReport) -> HeldStore:
        self.report = report
        return self

    def load(self) -> dict[str, Any]:
        return copy.deepcopy(self.disk)

    def save(self, data: dict[str, Any]) -> None:
        self.waiting.append(copy.deepcopy(data))

    def erase(self) -> None:
        self.disk = {}
        self.waiting.clear()

    def settle(self, failure: StorageError | None = None) -> None:
        """Write the latest waiting image (coalesced, as the daemon's writer does) and report."""
        if failure is None:
            self.disk = self.waiting[-1]
        self.writes += 1
        self.waiting.clear()
        self.report(failure)


@pytest.fixture
def store() -> HeldStore:
    return HeldStore()


@pytest.fixture
def held(store: HeldStore) -> Harness:
    return Harness(services=DeviceServices(stores=store.open))


def settle(h: Harness, store: HeldStore, failure: StorageError | None = None) -> bytes:
    """What the host does when the write is done: bring the model to now, hand it the outcome."""
    h.wait(0)
    store.settle(failure)
    h.wait(0)
    return h.output()


def test_ss_z_replies_once_the_store_has_it_and_lines_wait_ms111_ms13(
    held: Harness, store: HeldStore
) -> None:
    assert held.cmd("S X=3.3") == ACK
    assert held.send(b"SS Z\rV\r") == b"", "no reply before the save is on disk"
    assert store.disk == {}
    assert settle(held, store) == ACK + VERSION
    assert store.disk["saved"]["axes"]["X"]["speed"] == 3.3
    held.restart()
    assert held.cmd("S X?") == b":A X=3.300000\r\n"


def test_halt_does_not_cut_a_save_short_ms76(held: Harness, store: HeldStore) -> None:
    assert held.send(b"SS Z\r\\\r") == b""
    assert settle(held, store) == ACK + ACK, "the save acks, then HALT runs (nothing was moving)"


def test_failed_background_save_still_acks_and_is_flagged_ms111(held: Harness, store: HeldStore) -> None:
    assert held.cmd("SS Z") == b""
    failure = StorageError("save", Path("/state/ms2000-0001.json"), "No space left on device")
    assert settle(held, store, failure) == ACK
    assert held.dev.storage_error == str(failure)
    (event,) = held.take_events("storage_error")
    assert event["op"] == "save" and event["t"] == held.t
    held.cmd("SS Z")
    assert settle(held, store) == ACK
    assert held.dev.storage_error is None


def test_ss_x_and_ss_y_wait_for_the_store_too_ms110(held: Harness, store: HeldStore) -> None:
    assert held.cmd("SS X") == b""
    assert settle(held, store) == ACK
    assert store.disk["pending_factory"] is True


def test_power_cycle_drops_a_reply_still_waiting_ms112(held: Harness, store: HeldStore) -> None:
    assert held.cmd("SS Z") == b""
    held.input("power_cycle")
    assert settle(held, store) == b""
    assert held.cmd("V") == VERSION


def test_queries_never_write_positions_ms111(held: Harness, store: HeldStore) -> None:
    for _ in range(50):
        assert held.cmd("W X Y Z") == b":A 0 0 0\r\n"
        held.wait(0.01)
    assert store.waiting == []


def test_positions_written_once_when_the_stage_comes_to_rest_ms111(held: Harness, store: HeldStore) -> None:
    held.cmd("M X=1000 Y=-500")
    held.wait(0.01)
    assert store.waiting == [], "nothing is written while the stage moves"
    held.idle()
    held.wait(0.5)
    assert len(store.waiting) == 1
    settle(held, store)
    # user mm of the whole encoder counts the axes landed on (MS-45)
    assert store.disk["positions"] == pytest.approx({"X": 0.1, "Y": -0.05, "Z": 0.0}, abs=1e-4)
    for _ in range(10):
        held.cmd("W X Y")
        held.wait(0.1)
    assert store.waiting == []
    held.restart()  # no power-off: as after kill -9
    assert held.cmd("W X Y") == b":A 1000 -500\r\n"


def test_origin_changes_are_written_like_a_rest_ms111(held: Harness, store: HeldStore) -> None:
    held.cmd("H X=200")
    assert store.waiting == [], "written once the positions have stayed put a moment"
    held.wait(POSITION_SAVE_DELAY_S)
    assert len(store.waiting) == 1
    held.cmd("Z")
    held.wait(POSITION_SAVE_DELAY_S)
    assert len(store.waiting) == 2
    held.cmd("SP X=1")
    held.wait(POSITION_SAVE_DELAY_S)
    assert store.waiting[-1]["positions"] is None, "SP X=1 forgets the saved positions"
    held.cmd("~")
    held.wait(POSITION_SAVE_DELAY_S)
    assert len(store.waiting) == 3, "a reset alone writes nothing (MS-112)"


def test_memory_store_writes_nothing_at_rest(ms: Harness) -> None:
    assert not ms.dev.power.flash.persistent
    ms.cmd("M X=1000")
    ms.idle()
    assert "positions" not in ms.dev.power.flash.data
