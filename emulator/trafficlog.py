"""`--log-traffic FILE`: every byte in and out as JSON lines (time, device, port, direction, hex, summary).

The log is a side channel: a disk that fills up or a file that cannot be written must never stop a
device from answering. The first failure is logged once and traffic logging stops; SIGUSR1
(`reopen`, as after log rotation) starts it again on a fresh file at the same path.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import time
from pathlib import Path
from typing import TextIO

log = logging.getLogger("stage_emu.traffic")


class TrafficLog:
    def __init__(self, path: Path) -> None:
        self.path = path
        self._stream: TextIO | None = None
        self._open()

    @property
    def active(self) -> bool:
        return self._stream is not None

    def _open(self) -> None:
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_CLOEXEC, 0o600)
        self._stream = os.fdopen(fd, "a", encoding="utf-8")

    def record(
        self, t: float, device: str, port: str, direction: str, data: bytes, summary: str | None
    ) -> None:
        if self._stream is None:
            return
        entry = {
            "t": round(t, 6),
            "wall": round(time.time(), 6),
            "device": device,
            "port": port,
            "dir": direction,
            "hex": data.hex(" "),
        }
        if summary:
            entry["summary"] = summary
        try:
            self._stream.write(json.dumps(entry, ensure_ascii=False) + "\n")
            self._stream.flush()
        except OSError as exc:
            log.error(
                "traffic log %s: cannot write (%s); traffic logging stopped, devices keep serving "
                "(SIGUSR1 reopens it)",
                self.path,
                exc.strerror or exc,
            )
            self._discard()

    def reopen(self) -> None:
        """Close and reopen the file (after rotation, or to resume after a write failure)."""
        self._discard()
        try:
            self._open()
        except OSError as exc:
            log.error("traffic log %s: cannot reopen (%s); traffic logging stays off", self.path, exc)
            return
        log.warning("traffic log %s reopened", self.path)

    def _discard(self) -> None:
        stream, self._stream = self._stream, None
        if stream is None:
            return
        # close() still closes the descriptor when its final flush fails (a full disk)
        with contextlib.suppress(OSError):
            stream.close()

    def close(self) -> None:
        self._discard()
