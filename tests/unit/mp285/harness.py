"""The MP-285 on the model harness (tests/support/model_harness.py): paced as the runner paces it,
the host set as the device by default, output read as bytes received or emissions in hex."""

from __future__ import annotations

from typing import Any

from emulator.device import DeviceServices, HostLine
from emulator.devices.mp285.model import Mp285Device
from emulator.profiles.profile import load_profile
from emulator.profiles.registry import family
from tests.support.model_harness import ModelHarness

CHAR = 10 / 9600  # one 8N1 character at 9600 baud
SAME = object()  # host settings: the device's own


class Bench(ModelHarness[Mp285Device]):
    def __init__(
        self,
        profile: str = "mp285",
        overrides: dict[str, Any] | None = None,
        host: Any = SAME,
        paced: bool = True,
    ) -> None:
        loaded = load_profile(profile, overrides)

        def make(now: float) -> Mp285Device:
            device = family("mp285").factory("mp285-0", loaded, now, DeviceServices())  # type: ignore[union-attr]
            assert isinstance(device, Mp285Device)
            return device

        super().__init__(make, paced=paced)
        settings: HostLine | None = self.device.line_settings() if host is SAME else host
        if settings is not None:
            self.line_changed(settings)

    run = ModelHarness.advance
    take = ModelHarness.take_received
    take_timed = ModelHarness.take_received_timed

    def emissions(self) -> list[tuple[float, str]]:
        """Drain the device's emissions as (due, hex), due rounded to the microsecond."""
        return [(round(e.due, 6), hexs(e.data)) for e in self.take_emissions()]


def hexs(data: bytes) -> str:
    return data.hex(" ").upper()
