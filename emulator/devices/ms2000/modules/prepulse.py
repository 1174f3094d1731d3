"""PREPULSE: OUT0 mode 8, the timed pre-pulse (MS-91).

The module only makes `TTL Y=8` available (without it the mode is `:N-4`, MS-118); the base TTL
output emulates the mode as mode 2, a pulse of `RT Y` ms at the end of every commanded move
[choice], so the module drives nothing itself.
"""

from __future__ import annotations

from emulator.devices.ms2000.modules import Module, register
from emulator.devices.ms2000.modules.capabilities import TtlOut

PREPULSE_MODE = 8


@register
class Prepulse(Module, TtlOut):
    name = "PREPULSE"
    out0_modes = frozenset({PREPULSE_MODE})
