"""A manual-clock harness for the MS-2000 model: bytes in, bytes out, time moved explicitly."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from emulator.device import HostServices
from emulator.devices.ms2000.model import Ms2000Device
from emulator.profile import Profile, load_profile


class Harness:
    """Drives one MS2000 model the way the runner does: advance before receive, deadlines honoured."""

    def __init__(
        self,
        profile: str | Profile = "ms2000",
        overrides: dict[str, Any] | None = None,
        state_dir: Path | None = None,
        t0: float = 0.0,
        services: HostServices | None = None,
    ) -> None:
        self.profile = profile if isinstance(profile, Profile) else load_profile(profile, overrides)
        #: a state directory is written at once (HostServices' default stores); `services` can
        #: hand in any store instead, e.g. one that writes only when the test says
        self.services = services or HostServices(state_dir)
        self.t = t0
        self.dev = Ms2000Device("dut", self.profile, t0, self.services)
        self.events: list[dict[str, Any]] = []
        self.emissions: list[tuple[float, bytes]] = []

    def restart(self) -> None:
        """A new model on the same state directory (or services): an emulator restart."""
        self.dev = Ms2000Device("dut", self.profile, self.t, self.services)

    def _collect(self) -> None:
        self.emissions.extend((e.due, e.data) for e in self.dev.take_output())
        self.events.extend(self.dev.take_events())

    def output(self) -> bytes:
        data = b"".join(d for _, d in self.emissions)
        self.emissions.clear()
        return data

    def send(self, data: bytes, chunk: int | None = None) -> bytes:
        """Write bytes at the current time (all at once, or in chunks) and return what came back."""
        self.wait(0)
        size = chunk or len(data) or 1
        for i in range(0, len(data), size):
            self.dev.advance(self.t)
            self.dev.receive(data[i : i + size], self.t)
            self.dev.advance(self.t)
            self._collect()
        return self.output()

    def cmd(self, text: str) -> bytes:
        return self.send(text.encode("latin-1") + b"\r")

    def wait(self, seconds: float) -> None:
        """Move time forward, running every internal event at its due instant."""
        end = self.t + seconds
        while True:
            due = self.dev.next_deadline()
            if due is None or due > end:
                break
            self.t = max(self.t, due)
            self.dev.advance(self.t)
            self._collect()
        self.t = end
        self.dev.advance(self.t)
        self._collect()

    def idle(self, limit: float = 120.0, step: float = 0.01) -> float:
        """Run until no axis is busy (what polling `/` until `N` does); returns the time it took."""
        start = self.t
        while self.dev.busy(self.t):
            if self.t - start > limit:
                raise AssertionError("controller still busy")
            self.wait(step)
        return self.t - start

    def input(self, which: str, /, **params: Any) -> Any:
        self.wait(0)
        result = self.dev.control_input(which, params, self.t)
        self._collect()
        return result

    def get(self, name: str) -> Any:
        return self.dev.observe(name, self.t)

    def take_events(self, name: str | None = None) -> list[dict[str, Any]]:
        events = [e for e in self.events if name is None or e["ev"] == name]
        self.events = [e for e in self.events if not (name is None or e["ev"] == name)]
        return events


@pytest.fixture
def make() -> Iterator[Callable[..., Harness]]:
    yield Harness


@pytest.fixture
def ms() -> Harness:
    return Harness()
