"""The MS-2000 on the model harness (tests/support/model_harness.py), unpaced: bytes in at the
current time, their replies back at once, time moved explicitly."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from emulator.device import DeviceServices
from emulator.devices.ms2000.model import Ms2000Device
from emulator.devices.ms2000.schema import build_schema
from emulator.profiles import registry
from emulator.profiles.profile import Profile, load_profile
from tests.support.model_harness import ModelHarness


class Harness(ModelHarness[Ms2000Device]):
    """One MS2000 model; the host's line is the model's business (`input("host_line", ...)`)."""

    def __init__(
        self,
        profile: str | Profile[Any] = "ms2000",
        overrides: dict[str, Any] | None = None,
        state_dir: Path | None = None,
        t0: float = 0.0,
        services: DeviceServices | None = None,
    ) -> None:
        self.profile = profile if isinstance(profile, Profile) else load_profile(profile, overrides)
        #: a state directory is written at once (DeviceServices' default stores); `services` can
        #: hand in any store instead, e.g. one that writes only when the test says
        self.services = services or DeviceServices(state_dir)

        def make(now: float) -> Ms2000Device:
            return Ms2000Device("dut", self.profile, now, self.services)

        super().__init__(make, t0=t0, paced=False)

    @property
    def dev(self) -> Ms2000Device:
        return self.device

    @property
    def t(self) -> float:
        return self.now

    @property
    def emissions(self) -> list[tuple[float, bytes]]:
        """The emissions not yet read by `output`."""
        return [(e.due, e.data) for e in self.emitted]

    def output(self) -> bytes:
        """Drain what the device has sent."""
        return b"".join(e.data for e in self.take_emissions())

    def send(self, data: bytes, chunk: int | None = None) -> bytes:
        """Write bytes at the current time (all at once, or in chunks) and return what came back."""
        size = chunk or len(data) or 1
        self.wait(0)
        for i in range(0, len(data), size):
            self.write(data[i : i + size])
        return self.output()

    def cmd(self, text: str) -> bytes:
        return self.send(text.encode("latin-1") + b"\r")

    def idle(self, limit: float = 120.0, step: float = 0.01) -> float:
        """Run until no axis is busy (what polling `/` until `N` does); returns the time it took."""
        start = self.t
        while self.dev.busy(self.t):
            if self.t - start > limit:
                raise AssertionError("controller still busy")
            self.wait(step)
        return self.t - start

    input = ModelHarness.control


@pytest.fixture
def make() -> Iterator[Callable[..., Harness]]:
    yield Harness


@pytest.fixture
def ms() -> Harness:
    return Harness()


@contextmanager
def schema_rebuilt() -> Iterator[None]:
    """The ms2000 family's schema built again, with the fields of modules a test registered, for
    the duration; the family as it was afterwards."""
    family = registry.family("ms2000")
    assert family is not None
    registry.register(dataclasses.replace(family, schema=build_schema()))
    try:
        yield
    finally:
        registry.register(family)
