"""Sutter MP-285 / MP-285A controller family, registered as `mp285`."""

from __future__ import annotations

from emulator.devices.mp285.model import Mp285Device
from emulator.devices.mp285.schema import Mp285Config
from emulator.profiles import registry

FAMILY = registry.register(
    registry.Family(
        "mp285",
        "Sutter MP-285 / MP-285A micromanipulator controller (binary protocol)",
        Mp285Config,
        Mp285Device,
    )
)
