"""Non-volatile device memory: one JSON file per device identity in the host's state directory.

A device model keeps its "flash" here so that saved settings survive power cycles and emulator
restarts, including a kill -9 in the middle of a write: every write goes to a temporary file in the
same directory, is flushed and fsynced, renamed over the old file, and the directory is fsynced. A
file that cannot be read back as a JSON object is reported, renamed aside
(`<name>.corrupt-<timestamp>`) and treated as empty. With no state directory nothing touches the
disk, but the in-memory copy still behaves like flash for the life of the model.
"""

from __future__ import annotations

import contextlib
import copy
import json
import logging
import os
import re
import tempfile
import time
from pathlib import Path
from typing import Any

log = logging.getLogger("stage_emu.nvstore")

_SAFE = re.compile(r"[^A-Za-z0-9._-]")


class NvStore:
    """The flash of one device, keyed by `device_id` (a profile value)."""

    def __init__(self, state_dir: Path | None, device_id: str) -> None:
        self.device_id = device_id
        self.path = None if state_dir is None else Path(state_dir) / f"{_SAFE.sub('_', device_id)}.json"
        self._data: dict[str, Any] = self._read()

    @property
    def persistent(self) -> bool:
        return self.path is not None

    def load(self) -> dict[str, Any]:
        """A copy of the stored object (empty when nothing was ever saved)."""
        return copy.deepcopy(self._data)

    def save(self, data: dict[str, Any]) -> None:
        """Replace the stored object. A failing disk is logged; the in-memory copy is kept."""
        self._data = copy.deepcopy(data)
        if self.path is None:
            return
        try:
            _write_atomic(self.path, json.dumps(self._data, sort_keys=True, indent=1))
        except OSError as exc:
            log.error("%s: cannot save non-volatile memory to %s: %s", self.device_id, self.path, exc)

    def erase(self) -> None:
        """Forget everything (factory-fresh flash) and remove the file. A failing disk is logged."""
        self._data = {}
        if self.path is None:
            return
        try:
            self.path.unlink(missing_ok=True)
        except OSError as exc:
            log.error("%s: cannot erase non-volatile memory %s: %s", self.device_id, self.path, exc)

    def _read(self) -> dict[str, Any]:
        if self.path is None:
            return {}
        try:
            raw = self.path.read_bytes()
        except FileNotFoundError:
            return {}
        except OSError as exc:
            log.error("%s: cannot read non-volatile memory %s: %s", self.device_id, self.path, exc)
            return {}
        try:
            data = json.loads(raw.decode("utf-8"))
        except (ValueError, RecursionError) as exc:  # bad UTF-8 is a ValueError; absurd nesting recurses
            self._set_aside(self.path, f"not valid UTF-8 JSON ({exc})")
            return {}
        if not isinstance(data, dict):
            self._set_aside(self.path, "not a JSON object")
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


def _write_atomic(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
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
