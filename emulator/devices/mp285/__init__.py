"""Sutter MP-285 / MP-285A controller family, registered as `mp285`."""

from __future__ import annotations

from emulator import registry
from emulator.devices.mp285.model import Mp285Device
from emulator.devices.mp285.schema import Mp285Config

FAMILY = registry.register(
    registry.Family(
        "mp285",
        "Sutter MP-285 / MP-285A micromanipulator controller (binary protocol)",
        Mp285Config,
        Mp285Device,
    )
)
