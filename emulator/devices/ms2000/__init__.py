"""ASI MS-2000 stage controller family: profile schema and model, registered as `ms2000`."""

from __future__ import annotations

from emulator.devices.ms2000.model import Ms2000Device
from emulator.devices.ms2000.modules import channels_of
from emulator.devices.ms2000.schema import SCHEMA
from emulator.profiles import registry

FAMILY = registry.register(
    registry.Family(
        "ms2000",
        "ASI MS-2000 stage controller (ASCII, low-level binary, modules)",
        SCHEMA,
        Ms2000Device,
        channels_of,
    )
)
