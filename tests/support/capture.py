"""What the `stage-emu capture` tests share: a profile file to serve, `describe --json` values, the
comparison of a captured profile with the served one, and a port that rewrites chosen replies."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import serial
from click.testing import CliRunner

from emulator.cli import main
from emulator.tools.capture.readings import Reading
from protocols.ms2000 import query_shape


def served_profile(directory: Path, parent: str, name: str = "served", **keys: Any) -> Path:
    """A profile file extending `parent` with `keys` (JSON is YAML)."""
    path = directory / f"{name}.yaml"
    path.write_text(json.dumps({"spec": 1, "extends": parent, **keys}))
    return path


def describe_values(profile: str | Path) -> dict[str, Any]:
    """`stage-emu describe --json PROFILE` as {path: value}."""
    result = CliRunner().invoke(main, ["describe", "--json", str(profile)])
    assert result.exit_code == 0, result.output
    return {row["path"]: row["value"] for row in json.loads(result.stdout)}


def _value(rows: dict[str, Any], reading: Reading) -> Any:
    """The value `describe` shows for a reading's field (a key under a mapping-valued field is
    looked up in that mapping)."""
    for cut in range(len(reading.path), 0, -1):
        dotted = ".".join(reading.path[:cut])
        if dotted in rows:
            value = rows[dotted]
            for key in reading.path[cut:]:
                value = value.get(key) if isinstance(value, dict) else None
            return value
    raise KeyError(reading.dotted)


def comparable(reading: Reading, rows: dict[str, Any]) -> Any:
    """A field's `describe` value as the controller shows it: the overshoot in whole counts
    (MS-58), a reply shape after its default (MS-35), the status template's first 24 bytes
    (MP-60: the rest are computed)."""
    value = _value(rows, reading)
    path = reading.path
    if path[-1] == "overshoot_mm":
        return int(value * rows[".".join((*path[:-1], "counts_per_mm"))])
    if path[:2] == ("knobs", "reply_shape_overrides"):
        return query_shape(path[2], {path[2]: value} if value else None).value
    if path[-1] == "status_template":
        return bytes.fromhex(value)[:24]
    return value


def mismatches(readings: Iterable[Reading], served: str | Path, captured: str | Path) -> list[str]:
    """The captured fields whose `describe` values differ between the two profiles."""
    served_rows, captured_rows = describe_values(served), describe_values(captured)
    return [
        f"{r.dotted}: served {comparable(r, served_rows)!r}, captured {comparable(r, captured_rows)!r}"
        for r in readings
        if r.captured and comparable(r, served_rows) != comparable(r, captured_rows)
    ]


class Rewriting:
    """A port that hands each reply to the query written just before through `rewrite` (by the
    query's bytes), and passes everything else on to `inner`."""

    def __init__(self, inner: serial.SerialBase, rewrites: dict[bytes, Callable[[bytes], bytes]]) -> None:
        self.inner = inner
        self.rewrites = rewrites
        self.last = b""

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    def __setattr__(self, name: str, value: Any) -> None:
        if name == "timeout":
            self.inner.timeout = value
        else:
            super().__setattr__(name, value)

    def write(self, data: bytes) -> int | None:
        self.last = data
        return self.inner.write(data)

    def _rewritten(self, reply: bytes) -> bytes:
        rewrite = self.rewrites.get(self.last)
        return reply if rewrite is None else rewrite(reply)

    def read_until(self, expected: bytes = b"\n", size: int | None = None) -> bytes:
        return self._rewritten(bytes(self.inner.read_until(expected, size)))

    def read(self, size: int = 1) -> bytes:
        return self._rewritten(bytes(self.inner.read(size)))
