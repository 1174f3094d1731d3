"""Non-volatile device memory: one JSON file per device identity in the host's state directory.

A device model keeps its "flash" here so that saved settings survive power cycles and emulator
restarts, including a kill -9 in the middle of a write: every write goes to a temporary file
`.<name>.<pid>.<random>.tmp` in the same directory, is flushed and fsynced, renamed over the old
file, and the directory is fsynced. The file is therefore always the old or the new one; what a kill
can leave behind is a temporary file, and the next store on that file removes those of writers that
are no longer running. A file that cannot be read back as a JSON object is reported, renamed aside
(`<name>.corrupt-<timestamp>`) and treated as empty. With no state directory nothing touches the
disk, but the in-memory copy still behaves like flash for the life of the model.

Failures to read, write or remove the file are logged and raised as `StorageError`; the caller
decides what the device does about them (the MS2000 acks `SS Z` anyway and raises a fault flag).

One process at a time owns a store file: a store claims it when it is opened (`claim`, an exclusive
`flock` on `.<name>.lock` beside it, with the owner's pid inside) and a store of another process is
refused with `StateInUse`, so two daemons (or a daemon and a `stageemu://...?state=DIR` port) never
overwrite each other's saves unseen. Stores of one process share the claim (a model and the one a
reset replaces it with); the kernel drops it with the process, so a killed owner blocks nobody.

A device model gets its store from the runner (`DeviceServices.open_store`, emulator/device.py) and
never sees a file. Two kinds hand the outcome of each save to a `report` callback instead of raising:
`ReportingStore` writes at once, on the caller's thread (unit tests, in-process hosting);
`DeferredStore`, opened from the daemon's `FlashWriter`, queues the image for a worker thread, so the
event loop never waits for a disk, and reports back through the loop.
"""

from __future__ import annotations

import contextlib
import copy
import json
import logging
import os
import re
import stat
import threading
import time
import weakref
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

from emulator.storage import runtime
from emulator.storage.runtime import pid_alive, write_private_atomic

log = logging.getLogger("stage_emu.nvstore")

_SAFE = re.compile(r"[^A-Za-z0-9._-]")
#: temporary files of versions that did not put the writer's pid in the name are removed only when
#: this old: such a writer may still be running, and none takes anywhere near this long to save
LEGACY_TEMP_AGE_S = 60.0


def encode(data: dict[str, Any]) -> str:
    """A store file's text: sorted and indented, for a person reading it."""
    return json.dumps(data, sort_keys=True, indent=1)


class StorageError(Exception):
    """A store file could not be loaded, saved or erased. The message is one line."""

    def __init__(self, op: str, path: Path, reason: str) -> None:
        super().__init__(f"cannot {op} {path}: {reason}")
        self.op = op
        self.path = path
        self.reason = reason


class StateInUse(ValueError):
    """Another process owns a store file. The message is one line naming the file and the owner's
    pid; hosts add how to go on (emulator/hosting/daemon.py: another --state-dir, or --no-state). A
    ValueError, as every other reason a `stageemu://` URL cannot be opened."""

    def __init__(self, path: Path, pid: int | None) -> None:
        owner = "another process" if pid is None else f"process {pid}"
        super().__init__(f"non-volatile memory {path} is in use by {owner}")
        self.path = path
        self.pid = pid


def lock_path(path: Path) -> Path:
    """The lock file of store file `path`: beside it, so every path to the file finds the same one."""
    return path.with_name(f".{path.name}.lock")


@dataclass
class _Held:
    fd: int
    users: int


#: this process's claims, by the lock file's (st_dev, st_ino): one flock per file, shared by its stores
_held: dict[tuple[int, int], _Held] = {}
_held_guard = threading.Lock()


class Claim:
    """One store's share of its process's claim on a file (see `claim`); `release` gives it up."""

    def __init__(self, key: tuple[int, int] | None) -> None:
        self._key = key

    @property
    def held(self) -> bool:
        return self._key is not None

    def release(self) -> None:
        """Give up this share; the lock goes with the last share of the process. Idempotent."""
        key, self._key = self._key, None
        if key is None:
            return
        with _held_guard:
            held = _held[key]
            held.users -= 1
            if held.users == 0:
                del _held[key]
                os.close(held.fd)  # releases the flock


def claim(path: Path) -> Claim:
    """Claim store file `path` for this process; StateInUse when another process holds it.

    A claim that cannot be made (a folder that cannot be created, a file system without locks) is
    logged and the store goes on unclaimed: its saves will report what is wrong with the folder.
    Off POSIX nothing is locked (the in-process URL runs on Windows, which has no `flock`)."""
    if not runtime.POSIX:
        return Claim(None)
    import fcntl  # POSIX only (see above)

    lock = lock_path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600)
    except FileExistsError:  # mkdir's word for a file where the folder should be
        return _unclaimed(path, f"{path.parent} is not a directory")
    except OSError as exc:
        return _unclaimed(path, exc.strerror or str(exc))
    with _held_guard:
        try:
            info = os.fstat(fd)
            key = (info.st_dev, info.st_ino)
            if key in _held:  # another store of this process (a symlinked folder finds it too)
                _held[key].users += 1
                os.close(fd)
                return Claim(key)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                owner = _read_pid(fd)
                os.close(fd)
                raise StateInUse(path, owner) from None
            # pid first, then cut: a reader sees the old pid or ours on the first line, never nothing
            mine = f"{os.getpid()}\n".encode()
            os.pwrite(fd, mine, 0)
            os.ftruncate(fd, len(mine))
        except OSError as exc:  # a file system without locks
            os.close(fd)
            return _unclaimed(path, exc.strerror or str(exc))
        _held[key] = _Held(fd, 1)
        return Claim(key)


def _unclaimed(path: Path, reason: str) -> Claim:
    log.warning("cannot lock %s (%s): another process could use it unseen", path, reason)
    return Claim(None)


def _read_pid(fd: int) -> int | None:
    try:
        first = os.pread(fd, 32, 0).split(b"\n", 1)[0]
    except OSError:
        return None
    return int(first) if first.isdigit() else None


class NvStore:
    """The flash of one device, keyed by `device_id` (a profile value).

    The file is read by the first `load()`; later loads return the in-memory copy, which `save()`
    replaces even when the disk write fails (the device's flash works for the life of the model).
    Opening a store claims its file (StateInUse: another process owns it); `close()`, or the store's
    collection, gives the claim up."""

    def __init__(self, state_dir: Path | None, device_id: str) -> None:
        self.device_id = device_id
        self.path = None if state_dir is None else Path(state_dir) / f"{_SAFE.sub('_', device_id)}.json"
        self._data: dict[str, Any] | None = None
        self._release: Callable[[], object] | None = None
        if self.path is not None:
            # claimed before anything is read or removed: a refused store touches nothing
            held = claim(self.path)
            if held.held:
                self._release = weakref.finalize(self, held.release)
            self._remove_orphaned_temps(self.path)

    @property
    def persistent(self) -> bool:
        return self.path is not None

    def close(self) -> None:
        """Give up the claim on the file (a later save still writes, unclaimed)."""
        if self._release is not None:
            self._release()

    def load(self) -> dict[str, Any]:
        """A copy of the stored object (empty when nothing was ever saved). Raises StorageError
        once when the file exists but cannot be read; the store is empty from then on."""
        if self._data is None:
            self._data = {}  # a read that raises is not retried: the flash is empty from then on
            self._data = self._read(self.path)
        return copy.deepcopy(self._data)

    def save(self, data: dict[str, Any]) -> None:
        """Replace the stored object. Raises StorageError when the disk write fails; the old file
        is then untouched and the in-memory copy holds `data`."""
        self._data = copy.deepcopy(data)
        if self.path is None:
            return
        failure = self.write_text(self._text())
        if failure is not None:
            raise failure

    def _text(self) -> str:
        return encode(self._data or {})

    def write_text(self, text: str) -> StorageError | None:
        """Write `text` atomically; the failure (logged) instead of raising it."""
        assert self.path is not None
        try:
            _write_atomic(self.path, text)
        except OSError as exc:
            return self._failure("save", self.path, exc)
        return None

    def erase(self) -> None:
        """Forget everything (factory-fresh flash) and remove the file. Raises StorageError when
        the file cannot be removed; the store then keeps its contents."""
        if self.path is not None:
            try:
                self.path.unlink(missing_ok=True)
            except OSError as exc:
                raise self._failure("erase", self.path, exc) from exc
        self._data = {}

    def _failure(self, op: str, path: Path, exc: OSError) -> StorageError:
        reason = exc.strerror or str(exc)
        if exc.filename is not None and str(exc.filename) != str(path):  # a temporary file, the directory
            reason += f": {exc.filename}"
        failure = StorageError(op, path, reason)
        failure.__cause__ = exc
        log.error("%s: %s", self.device_id, failure)
        return failure

    def _read(self, path: Path | None) -> dict[str, Any]:
        if path is None:
            return {}
        try:
            raw = path.read_bytes()
        except FileNotFoundError:
            return {}
        except OSError as exc:
            raise self._failure("load", path, exc) from exc
        try:
            data = json.loads(raw.decode("utf-8"))
        except (ValueError, RecursionError) as exc:  # bad UTF-8 is a ValueError; absurd nesting recurses
            self._set_aside(path, f"not valid UTF-8 JSON ({exc})")
            return {}
        if not isinstance(data, dict):
            self._set_aside(path, "not a JSON object")
            return {}
        return data

    def _set_aside(self, path: Path, why: str) -> None:
        stamp = time.strftime("%Y%m%dT%H%M%S")
        aside = path.with_name(f"{path.name}.corrupt-{stamp}")
        serial = 1
        while aside.exists():  # a second corrupt file within the same second keeps the first
            serial += 1
            aside = path.with_name(f"{path.name}.corrupt-{stamp}-{serial}")
        try:
            path.rename(aside)
        except OSError as exc:
            log.error("%s: %s is corrupt (%s) and cannot be moved aside: %s", self.device_id, path, why, exc)
            return
        log.warning(
            "%s: non-volatile memory %s is corrupt (%s); moved it to %s and starting from factory settings",
            self.device_id,
            path,
            why,
            aside,
        )

    def _remove_orphaned_temps(self, path: Path) -> None:
        """Remove this file's temporary files left by writers that were killed mid-save: those whose
        pid is no longer a process, and pid-less ones of earlier versions once they are old. Only
        regular files with our exact temp-name pattern are touched; symlinks are never followed."""
        name = re.escape(path.name)
        current = re.compile(rf"\.{name}\.(\d+)\.[A-Za-z0-9_]+\.tmp")
        legacy = re.compile(rf"\.{name}\.[A-Za-z0-9_]+\.tmp")
        try:
            names = os.listdir(path.parent)
        except FileNotFoundError:
            return
        except OSError as exc:
            log.warning(
                "%s: cannot look for orphaned temporary files in %s: %s", self.device_id, path.parent, exc
            )
            return
        removed = 0
        for entry in names:
            owner = current.fullmatch(entry)
            if owner is None and legacy.fullmatch(entry) is None:
                continue
            candidate = path.parent / entry
            try:
                info = candidate.lstat()
                if not stat.S_ISREG(info.st_mode):
                    continue
                if owner is not None and pid_alive(int(owner.group(1))):
                    continue
                if owner is None and time.time() - info.st_mtime < LEGACY_TEMP_AGE_S:
                    continue
                candidate.unlink()
            except FileNotFoundError:
                continue  # another store on the same file removed it first
            except OSError as exc:
                log.warning(
                    "%s: cannot remove orphaned temporary file %s: %s", self.device_id, candidate, exc
                )
                continue
            removed += 1
        if removed:
            log.info(
                "%s: removed %d orphaned temporary file(s) of %s left by a killed writer",
                self.device_id,
                removed,
                path.name,
            )


def _write_atomic(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    write_private_atomic(path, text, sync_dir=True)


#: what a store tells its model about a save: None once written, else the (logged) StorageError
Report = Callable[[StorageError | None], None]


class ReportingStore(NvStore):
    """An NvStore whose saves never raise: each outcome goes to `report` before `save` returns.
    What `DeviceServices` hands a model when the host has no writer thread (unit tests, in-process)."""

    def __init__(self, state_dir: Path | None, device_id: str, report: Report) -> None:
        super().__init__(state_dir, device_id)
        self.report = report

    def save(self, data: dict[str, Any]) -> None:
        try:
            super().save(data)
        except StorageError as failure:
            self.report(failure)
        else:
            self.report(None)


class DeferredStore(ReportingStore):
    """A store of the daemon: `save` keeps the image in memory and queues it on its FlashWriter.
    `report` runs on the host's thread once the store has settled (the latest image is on disk, or
    its write failed); an image replaced before it was written is never reported on its own. Loads
    and erases stay synchronous: they happen once per model (start-up, factory reset)."""

    def __init__(self, writer: FlashWriter, state_dir: Path, device_id: str, report: Report) -> None:
        super().__init__(state_dir, device_id, report)
        self._writer = writer
        #: images saved so far; the writer hands back the number of the one it wrote
        self._saved = 0

    def save(self, data: dict[str, Any]) -> None:
        # A shallow copy, encoded on the writer's thread: a model replaces the sections it saves and
        # never changes one in place (`Flash.write`), so this image cannot change under the writer,
        # and the loop spends no time on a deep copy or on JSON per save (one per move at rest).
        self._data = dict(data)
        self._saved += 1
        self._writer.submit(self, self._saved, self._data)

    def written(self, number: int, failure: StorageError | None) -> None:
        """The writer wrote image `number` (on the host's thread)."""
        if number == self._saved:
            self.report(failure)

    def erase(self) -> None:
        dropped = self._writer.drop(self)  # after this no write of ours can land behind the unlink
        try:
            super().erase()
        except StorageError:
            if dropped is not None:
                self._writer.submit(self, *dropped)
            raise


class FlashWriter:
    """The daemon's flash: DeferredStores whose files are written on one worker thread, off the
    event loop (rule 2 of the design), atomically as NvStore writes them.

    Coalesced: a store has at most one image waiting; a newer save replaces it, so a burst of saves
    costs one write of the latest image. `deliver(callable)` must run the callable on the host's
    thread (the loop's `call_soon_threadsafe`): outcomes go back through it. `close()` writes every
    waiting image before it returns, so a clean shutdown (SIGTERM) loses no save, then gives up
    the stores' claims on their files."""

    def __init__(self, state_dir: Path, deliver: Callable[[Callable[[], None]], object]) -> None:
        self.state_dir = state_dir
        self._deliver = deliver
        self._cond = threading.Condition()
        #: per store, the latest image not yet taken by the worker: (its number, the image)
        self._waiting: dict[DeferredStore, tuple[int, dict[str, Any]]] = {}
        self._busy: DeferredStore | None = None
        self._thread: threading.Thread | None = None
        self._closed = False
        #: the stores opened here that are still in use, whose claims `close` gives up
        self._stores: weakref.WeakSet[DeferredStore] = weakref.WeakSet()

    def open(self, device_id: str, report: Report) -> DeferredStore:
        store = DeferredStore(self, self.state_dir, device_id, report)
        self._stores.add(store)
        return store

    def submit(self, store: DeferredStore, number: int, image: dict[str, Any]) -> None:
        with self._cond:
            if not self._closed:
                self._waiting[store] = (number, image)
                if self._thread is None:
                    self._thread = threading.Thread(target=self._run, name="flash-writer", daemon=True)
                    self._thread.start()
                self._cond.notify_all()
                return
            # after close the caller writes; an older image of this store must not land after it
            self._waiting.pop(store, None)
            while self._busy is store:
                self._cond.wait()
        store.written(number, store.write_text(encode(image)))

    def drop(self, store: DeferredStore) -> tuple[int, dict[str, Any]] | None:
        """Forget the image `store` has waiting (returned) and wait for its write in progress."""
        with self._cond:
            dropped = self._waiting.pop(store, None)
            while self._busy is store:
                self._cond.wait()
        return dropped

    def close(self) -> None:
        """Write what is waiting, stop the worker, give up the claims. Blocks; later saves are
        written at once (unclaimed: the process is on its way out)."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()
            thread = self._thread
        if thread is not None:
            thread.join()
        for store in list(self._stores):
            store.close()

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._waiting and not self._closed:
                    self._cond.wait()
                if not self._waiting:
                    return
                store = next(iter(self._waiting))
                number, image = self._waiting.pop(store)
                self._busy = store
            failure = store.write_text(encode(image))
            with self._cond:
                self._busy = None
                self._cond.notify_all()
            # a closed loop raises RuntimeError: the process is exiting, nobody is left to tell
            with contextlib.suppress(RuntimeError):
                self._deliver(partial(store.written, number, failure))
