"""ENC_INT: the encoder-pulse interrupt of SCAN builds (§9.0, MS-SCAN-4).

In these builds the interrupt line that INO_INT serves for IN0 is wired to the scanned axis's
encoder, and `TTL X=1` enables it: SCAN MODULE then counts pixel pulses. The module only makes
`TTL X=1` available and marks counting as possible; it serves no IN0 function of its own (a RING
BUFFER listed before it still steps on a mode-1 trigger such as a bare `RM`).
"""

from __future__ import annotations

from emulator.devices.ms2000.modules import Module, register
from emulator.devices.ms2000.modules.capabilities import In0Interrupt, TtlIn

#: `TTL X=1` enables encoder-pulse counting
COUNTING_MODE = 1


@register
class EncInt(Module, TtlIn, In0Interrupt):
    name = "ENC_INT"
    in0_modes = frozenset({COUNTING_MODE})
