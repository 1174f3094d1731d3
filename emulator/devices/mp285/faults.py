"""Field failure modes of the MP-285 (docs/mp285.md §12): what a crashed controller sends and what
recovers it (MP-77, MP-78), the rotary encoder and its crash window (MP-79), and the control-channel
parameters that inject them. The device enters and leaves CRASHED, POWERING_ON and LOCKED itself.
"""

from __future__ import annotations

from typing import Any

from emulator.device import ControlError
from emulator.devices.mp285.schema import SIGNATURE_BYTES, Mp285Knobs
from protocols import mp285 as proto
from protocols.mp285 import CR, CTRL_C

CR_BURST = 200  # MP-78
SIGNATURE_LENGTH = 16  # MP-77


class Crash:
    """The signature of the current (or last) crash and the recovery the profile allows."""

    def __init__(self, knobs: Mp285Knobs) -> None:
        self.profile_signature = SIGNATURE_BYTES[knobs.crash_signature]
        self.signature = self.profile_signature
        self._recovery: str = knobs.crash_recovery
        self._cr_run = 0

    def start(self, signature: bytes) -> bytes:
        """MP-77: a crash with this signature; returns the bytes sent at once."""
        self.signature = signature
        self._cr_run = 0
        return signature * SIGNATURE_LENGTH

    def on_byte(self, byte: int, framing_error: bool) -> tuple[bool, bytes]:
        """A byte received while CRASHED: (recovered, reply). Recovery is a reset without the DEAF
        period (MP-78); a ^C that recovers is answered `0D`, other bytes get one signature byte."""
        clean = not framing_error
        if self._recovery == "ctrl_c" and clean and byte == CTRL_C:
            return True, b"\r"
        if self._recovery == "cr_burst":
            self._cr_run = self._cr_run + 1 if clean and byte == CR else 0
            if self._cr_run >= CR_BURST:
                return True, b""
        return False, self.signature


def crash_signature(params: dict[str, Any], default: str) -> bytes:
    """The `crash` input's signature (`signature`, or `crash_signature` as in profiles)."""
    signature = params.get("signature", params.get("crash_signature", default))
    if not isinstance(signature, str) or signature not in SIGNATURE_BYTES:
        raise ControlError(f"signature must be one of {', '.join(SIGNATURE_BYTES)}, got {signature!r}")
    return SIGNATURE_BYTES[signature]


class Roe:
    """The rotary encoder (MP-79): when it was last turned, and whether a byte now crashes the unit."""

    def __init__(self, knobs: Mp285Knobs) -> None:
        self._crashes: bool = knobs.roe_crash
        low, high = knobs.roe_crash_window_s
        self._low: float = low
        self._high: float = high
        #: when the ROE was last turned; None since power-on or a crash
        self.last: float | None = None

    def crash_due(self, t: float) -> bool:
        """MP-79: a byte received in the window after the last click triggers a crash."""
        if not self._crashes or self.last is None:
            return False
        return self._low <= t - self.last < self._high


def roe_turn(params: dict[str, Any]) -> tuple[int, int]:
    """The `roe` input's axis (index) and clicks."""
    axis = str(params.get("axis", "")).upper()
    clicks = params.get("clicks")
    if axis not in proto.AXES:
        raise ControlError(f"roe needs axis X, Y or Z, got {params.get('axis')!r}")
    if isinstance(clicks, bool) or not isinstance(clicks, int):
        raise ControlError(f"roe needs clicks (an integer), got {clicks!r}")
    return proto.AXES.index(axis), clicks
