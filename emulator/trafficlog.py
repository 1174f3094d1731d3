"""`--log-traffic FILE`: every byte in and out as JSON lines (time, device, port, direction, hex, summary)."""

from __future__ import annotations

import json
import time
from typing import TextIO


class TrafficLog:
    def __init__(self, stream: TextIO) -> None:
        self._stream = stream

    def record(
        self, t: float, device: str, port: str, direction: str, data: bytes, summary: str | None
    ) -> None:
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
        self._stream.write(json.dumps(entry, ensure_ascii=False) + "\n")
        self._stream.flush()

    def close(self) -> None:
        self._stream.close()
