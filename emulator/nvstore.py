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
"""

from __future__ import annotations

import contextlib
import copy
import json
import logging
import os
import re
import stat
import tempfile
import time
from pathlib import Path
from typing import Any

log = logging.getLogger("stage_emu.nvstore")

_SAFE = re.compile(r"[^A-Za-z0-9._-]")
#: temporary files of versions that did not put the writer's pid in the name are removed only when
#: this old: such a writer may still be running, and none takes anywhere near this long to save
LEGACY_TEMP_AGE_S = 60.0


class StorageError(Exception):
    """A store file could not be loaded, saved or erased. The message is one line."""

    def __init__(self, op: str, path: Path, reason: str) -> None:
        super().__init__(f"cannot {op} {path}: {reason}")
        self.op = op
        self.path = path
        self.reason = reason


class NvStore:
    """The flash of one device, keyed by `device_id` (a profile value).

    The file is read by the first `load()`; later loads return the in-memory copy, which `save()`
    replaces even when the disk write fails (the device's flash works for the life of the model)."""

    def __init__(self, state_dir: Path | None, device_id: str) -> None:
        self.device_id = device_id
        self.path = None if state_dir is None else Path(state_dir) / f"{_SAFE.sub('_', device_id)}.json"
        self._data: dict[str, Any] | None = None
        if self.path is not None:
            self._remove_orphaned_temps(self.path)

    @property
    def persistent(self) -> bool:
        return self.path is not None

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
        try:
            _write_atomic(self.path, json.dumps(self._data, sort_keys=True, indent=1))
        except OSError as exc:
            raise self._failure("save", self.path, exc) from exc

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
                if owner is not None and _running(int(owner.group(1))):
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


def _running(pid: int) -> bool:
    """Whether `pid` may still be a process (writing its temporary file). Only "no such process"
    counts as gone: a process of another user, or a number the system rejects, is left alone."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (OSError, OverflowError):
        pass
    return True


def _write_atomic(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    # the pid in the name tells a later store whether the writer is still alive (see above)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    dir_fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)
