"""NvStore: failures are raised as StorageError (never swallowed), writes stay atomic when the disk
fails, temporary files orphaned by a killed writer are removed at the next start (MS-111), and one
process at a time owns a store file."""

from __future__ import annotations

import errno
import json
import logging
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from emulator.storage import nvstore, runtime
from emulator.storage.nvstore import (
    LEGACY_TEMP_AGE_S,
    FlashWriter,
    NvStore,
    ReportingStore,
    StateInUse,
    StorageError,
    lock_path,
)

ROOT = Path(__file__).resolve().parents[2]


def disk_full(fd: int) -> None:
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def dead_pid() -> int:
    """The pid of a process that has exited and been reaped."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


@pytest.fixture
def live_child() -> Iterator[int]:
    """A running process other than this one (it reads stdin until the test closes it)."""
    child = subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.read()"], stdin=subprocess.PIPE)
    yield child.pid
    assert child.stdin is not None
    child.stdin.close()
    child.wait()


def test_save_on_a_full_disk_raises_and_leaves_the_old_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    store = NvStore(tmp_path, "dev")
    store.save({"v": 1})
    monkeypatch.setattr(nvstore.os, "fsync", disk_full)
    with caplog.at_level(logging.ERROR), pytest.raises(StorageError) as failure:
        store.save({"v": 2})
    assert failure.value.op == "save" and failure.value.path == tmp_path / "dev.json"
    assert failure.value.reason == "No space left on device"
    assert str(failure.value) == f"cannot save {tmp_path / 'dev.json'}: No space left on device"
    assert "cannot save" in caplog.text
    assert store.load() == {"v": 2}, "the in-memory flash holds the new data for the life of the model"
    monkeypatch.undo()
    assert NvStore(tmp_path, "dev").load() == {"v": 1}
    assert sorted(os.listdir(tmp_path)) == [".dev.json.lock", "dev.json"], "the temporary file is gone"


def test_save_into_an_unusable_state_dir_raises(tmp_path: Path) -> None:
    blocker = tmp_path / "state"
    blocker.write_text("a file where the directory should be")
    store = NvStore(blocker, "dev")
    with pytest.raises(StorageError, match="cannot save"):
        store.save({"v": 1})


def test_unreadable_file_raises_once_then_reads_as_empty(tmp_path: Path) -> None:
    (tmp_path / "dev.json").mkdir()
    store = NvStore(tmp_path, "dev")
    with pytest.raises(StorageError) as failure:
        store.load()
    assert failure.value.op == "load"
    assert store.load() == {}


def test_erase_failure_raises_and_keeps_the_contents(tmp_path: Path) -> None:
    (tmp_path / "dev.json").write_text('{"v": 1}')
    store = NvStore(tmp_path, "dev")
    assert store.load() == {"v": 1}
    (tmp_path / "dev.json").unlink()
    (tmp_path / "dev.json").mkdir()  # unlink() of a directory fails
    with pytest.raises(StorageError) as failure:
        store.erase()
    assert failure.value.op == "erase"
    assert store.load() == {"v": 1}


def test_temporary_file_names_carry_the_writer_pid(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    renamed: list[str] = []
    replace = os.replace

    def spy(src: str, dst: str) -> None:
        renamed.append(Path(src).name)
        replace(src, dst)

    monkeypatch.setattr(nvstore.os, "replace", spy)
    NvStore(tmp_path, "dev").save({})
    (name,) = renamed
    assert name.startswith(f".dev.json.{os.getpid()}.") and name.endswith(".tmp")


def test_orphaned_temporary_files_of_dead_writers_are_removed(
    tmp_path: Path, live_child: int, caplog: pytest.LogCaptureFixture
) -> None:
    gone = dead_pid()
    orphan = tmp_path / f".dev.json.{gone}.abc_123x.tmp"
    kept = {
        f".dev.json.{os.getpid()}.k3j4h5g6.tmp": "this process may be writing",
        f".dev.json.{live_child}.k3j4h5g6.tmp": "another live process may be writing",
        f".other.json.{gone}.k3j4h5g6.tmp": "another store's",
        f"dev.json.{gone}.k3j4h5g6.tmp": "no leading dot",
        f".dev.json.{gone}.k3j4h5g6.tmp.bak": "not our suffix",
        "dev.json.corrupt-20240101T000000": "kept for inspection",
    }
    for name in [orphan.name, *kept]:
        (tmp_path / name).write_text("x")
    target = tmp_path / "target"
    target.write_text("keep me")
    (tmp_path / f".dev.json.{gone}.symlink1.tmp").symlink_to(target)
    (tmp_path / f".dev.json.{gone}.dirdir12.tmp").mkdir()
    with caplog.at_level(logging.INFO, logger="stage_emu.nvstore"):
        NvStore(tmp_path, "dev")
    assert not orphan.exists()
    for name, why in kept.items():
        assert (tmp_path / name).exists(), why
    assert (tmp_path / f".dev.json.{gone}.symlink1.tmp").is_symlink() and target.read_text() == "keep me"
    assert (tmp_path / f".dev.json.{gone}.dirdir12.tmp").is_dir()
    assert "removed 1 orphaned temporary file" in caplog.text


def test_pidless_temporary_files_of_earlier_versions_are_removed_once_old(tmp_path: Path) -> None:
    old = tmp_path / ".dev.json.a1b2c3d4.tmp"
    fresh = tmp_path / ".dev.json.e5f6g7h8.tmp"
    for path in (old, fresh):
        path.write_text("x")
    stale = os.stat(old).st_mtime - LEGACY_TEMP_AGE_S - 1
    os.utime(old, (stale, stale))
    NvStore(tmp_path, "dev")
    assert not old.exists()
    assert fresh.exists(), "a writer of an earlier version may still be renaming it"


# ---- stores handed to device models: reporting, and the daemon's writer thread ----------------


class Loop:
    """Stands in for the event loop: callables the writer hands back run when the test says."""

    def __init__(self) -> None:
        self._ready: list[Callable[[], None]] = []
        self._lock = threading.Lock()

    def deliver(self, action: Callable[[], None]) -> None:
        with self._lock:
            self._ready.append(action)

    def run(self) -> int:
        with self._lock:
            ready, self._ready = self._ready, []
        for action in ready:
            action()
        return len(ready)


@dataclass
class Gate:
    """Holds each disk write until `release` is set; records each write's text and thread."""

    release: threading.Event = field(default_factory=threading.Event)
    started: threading.Event = field(default_factory=threading.Event)
    writes: list[tuple[str, str]] = field(default_factory=list)

    def values(self) -> list[int]:
        return [json.loads(text)["v"] for text, _ in self.writes]


@pytest.fixture
def gate(monkeypatch: pytest.MonkeyPatch) -> Iterator[Gate]:
    gate = Gate()
    write = nvstore._write_atomic

    def held(path: Path, text: str) -> None:
        gate.writes.append((text, threading.current_thread().name))
        gate.started.set()
        gate.release.wait(5)
        write(path, text)

    monkeypatch.setattr(nvstore, "_write_atomic", held)
    yield gate
    gate.release.set()


def test_reporting_store_reports_each_save_instead_of_raising(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    outcomes: list[StorageError | None] = []
    store = ReportingStore(tmp_path, "dev", outcomes.append)
    store.save({"v": 1})
    monkeypatch.setattr(nvstore.os, "fsync", disk_full)
    store.save({"v": 2})
    assert outcomes[0] is None and isinstance(outcomes[1], StorageError)
    assert store.load() == {"v": 2}
    assert ReportingStore(None, "m", outcomes.append).persistent is False


def test_writer_writes_off_the_callers_thread_coalesced_and_reports_once(tmp_path: Path, gate: Gate) -> None:
    loop = Loop()
    writer = FlashWriter(tmp_path, loop.deliver)
    outcomes: list[StorageError | None] = []
    store = writer.open("dev", outcomes.append)
    store.save({"v": 1})
    assert gate.started.wait(5)
    for v in (2, 3, 4):
        store.save({"v": v})  # the first write is on the disk's time: these wait, replacing each other
    assert not (tmp_path / "dev.json").exists() and store.load() == {"v": 4}
    gate.release.set()
    writer.close()
    assert gate.values() == [1, 4]
    assert {name for _, name in gate.writes} == {"flash-writer"}
    assert json.loads((tmp_path / "dev.json").read_text()) == {"v": 4}
    assert loop.run() == 2 and outcomes == [None], "only the settled store is reported"


def test_close_writes_every_waiting_image(tmp_path: Path) -> None:
    """What a SIGTERM'd daemon does last: nothing saved is lost."""
    writer = FlashWriter(tmp_path, Loop().deliver)
    stores = [writer.open(f"dev{i}", lambda failure: None) for i in range(3)]
    for i, store in enumerate(stores):
        store.save({"v": i})
    writer.close()
    assert [json.loads((tmp_path / f"dev{i}.json").read_text()) for i in range(3)] == [
        {"v": i} for i in range(3)
    ]
    stores[0].save({"v": 9})  # after close: written at once
    assert json.loads((tmp_path / "dev0.json").read_text()) == {"v": 9}
    assert not list(tmp_path.glob(".*.tmp"))


def test_failed_background_write_is_reported_through_the_loop(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    loop = Loop()
    writer = FlashWriter(tmp_path, loop.deliver)
    outcomes: list[StorageError | None] = []
    monkeypatch.setattr(nvstore.os, "fsync", disk_full)
    writer.open("dev", outcomes.append).save({"v": 1})
    writer.close()
    assert outcomes == [], "reports run on the host's thread only"
    loop.run()
    (failure,) = outcomes
    assert isinstance(failure, StorageError) and failure.reason == "No space left on device"


def test_erase_drops_the_waiting_image_and_waits_for_the_write_in_progress(
    tmp_path: Path, gate: Gate
) -> None:
    writer = FlashWriter(tmp_path, Loop().deliver)
    store = writer.open("dev", lambda failure: None)
    store.save({"v": 1})
    assert gate.started.wait(5)
    store.save({"v": 2})
    threading.Timer(0.05, gate.release.set).start()
    store.erase()  # returns once the write of v1 has landed, then removes it
    writer.close()
    assert not (tmp_path / "dev.json").exists()
    assert gate.values() == [1]
    assert store.load() == {}


# ---- one owner per store file ------------------------------------------------------------------

#: another process: opens the store named on its command line, says so, and keeps it until killed
HOLDER = (
    "import sys; from pathlib import Path; from emulator.storage.nvstore import NvStore;"
    "store = NvStore(Path(sys.argv[1]), sys.argv[2]); store.save({'by': 'holder'});"
    "print('held', flush=True); sys.stdin.read()"
)
#: another process: tries to open the store, prints the refusal or `opened`
TRY = (
    "import sys; from pathlib import Path; from emulator.storage.nvstore import NvStore, StateInUse\n"
    "try:\n    NvStore(Path(sys.argv[1]), sys.argv[2])\n"
    "except StateInUse as exc:\n    print(exc)\nelse:\n    print('opened')"
)


#: the children import this checkout's emulator package
CHILD_ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def python(code: str, *args: str) -> list[str]:
    return [sys.executable, "-c", code, *args]


def other_process_opens(state: Path, device_id: str = "dev") -> str:
    """What another process gets when it opens the store now."""
    done = subprocess.run(
        python(TRY, str(state), device_id), env=CHILD_ENV, capture_output=True, text=True, timeout=30
    )
    assert done.returncode == 0 and not done.stderr, done.stderr
    return done.stdout.strip()


@pytest.fixture
def holder(tmp_path: Path) -> Iterator[subprocess.Popen[str]]:
    """Another process that owns `tmp_path`'s store "dev" (and has saved into it)."""
    child = subprocess.Popen(
        python(HOLDER, str(tmp_path), "dev"),
        env=CHILD_ENV,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert child.stdout is not None and child.stdout.readline() == "held\n"
    yield child
    if child.poll() is None:
        child.kill()
    child.wait()


def test_a_store_file_owned_by_another_process_is_refused_with_its_pid(
    tmp_path: Path, holder: subprocess.Popen[str]
) -> None:
    gone = dead_pid()
    orphan = tmp_path / f".dev.json.{gone}.abc_123x.tmp"
    orphan.write_text("x")
    with pytest.raises(StateInUse) as refused:
        NvStore(tmp_path, "dev")
    assert refused.value.pid == holder.pid and refused.value.path == tmp_path / "dev.json"
    assert (
        str(refused.value) == f"non-volatile memory {tmp_path / 'dev.json'} is in use by process {holder.pid}"
    )
    assert isinstance(refused.value, ValueError), "what a stageemu:// URL raises for what it cannot open"
    assert orphan.exists(), "a refused store touches nothing"
    assert json.loads((tmp_path / "dev.json").read_text()) == {"by": "holder"}
    assert NvStore(tmp_path, "other").load() == {}, "another device's file in the same folder is free"


def test_a_killed_owner_blocks_nobody(tmp_path: Path, holder: subprocess.Popen[str]) -> None:
    holder.send_signal(signal.SIGKILL)
    holder.wait()
    store = NvStore(tmp_path, "dev")  # the kernel dropped the lock with the process
    assert store.load() == {"by": "holder"}
    assert lock_path(tmp_path / "dev.json").read_text() == f"{os.getpid()}\n"
    assert (
        other_process_opens(tmp_path)
        == f"non-volatile memory {tmp_path / 'dev.json'} is in use by process {os.getpid()}"
    )


def test_stores_of_one_process_share_the_claim_until_the_last_lets_go(tmp_path: Path) -> None:
    """A model and the one a reset replaces it with, or the next open of a URL, are one owner; a
    symlinked folder reaches the same file and the same claim."""
    (tmp_path / "state").mkdir()
    (tmp_path / "alias").symlink_to(tmp_path / "state")
    first = NvStore(tmp_path / "state", "dev")
    second = NvStore(tmp_path / "alias", "dev")
    first.close()
    assert "in use by process" in other_process_opens(tmp_path / "state")
    second.close()
    second.close()  # idempotent
    assert other_process_opens(tmp_path / "state") == "opened"


def test_a_collected_store_gives_up_its_claim(tmp_path: Path) -> None:
    store = NvStore(tmp_path, "dev")
    assert "in use" in other_process_opens(tmp_path)
    del store  # no cycle: collected at once
    assert other_process_opens(tmp_path) == "opened"


def test_flash_writer_close_gives_up_its_stores_claims(tmp_path: Path) -> None:
    writer = FlashWriter(tmp_path, Loop().deliver)
    store = writer.open("dev", lambda failure: None)
    store.save({"v": 1})
    assert "in use" in other_process_opens(tmp_path)
    writer.close()
    assert other_process_opens(tmp_path) == "opened"
    assert json.loads((tmp_path / "dev.json").read_text()) == {"v": 1}


def test_a_store_that_cannot_be_locked_works_and_says_why(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    blocker = tmp_path / "state"
    blocker.write_text("a file where the directory should be")
    with caplog.at_level(logging.WARNING, logger="stage_emu.nvstore"):
        store = NvStore(blocker, "dev")
    assert f"cannot lock {blocker / 'dev.json'} ({blocker} is not a directory)" in caplog.text
    with pytest.raises(StorageError, match="cannot save"):  # what the device then reports, as before
        store.save({"v": 1})


def test_off_posix_nothing_is_locked(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Windows has no flock: the in-process URL's `state=DIR` works there unclaimed."""
    monkeypatch.setattr(runtime, "POSIX", False)
    store = NvStore(tmp_path, "dev")
    store.save({"v": 1})
    assert not lock_path(tmp_path / "dev.json").exists()
