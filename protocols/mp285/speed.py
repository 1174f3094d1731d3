"""MP-285 speeds: the `V` velocity word (MP-37) and the speed limits per resolution (MP-38, MP-39)."""

from __future__ import annotations

from dataclasses import dataclass

HIGH_RESOLUTION_BIT = 0x8000


@dataclass(frozen=True)
class Velocity:
    """The `V` word: bit 15 = high resolution (fine, 50 µsteps/step), bits 14-0 = speed in µm/s."""

    speed: int
    high: bool = False

    def __post_init__(self) -> None:
        if not 0 <= self.speed <= 0x7FFF:
            raise ValueError(f"speed {self.speed} does not fit 15 bits")

    @property
    def word(self) -> int:
        return (HIGH_RESOLUTION_BIT if self.high else 0) | self.speed

    @classmethod
    def from_word(cls, word: int) -> Velocity:
        return cls(word & 0x7FFF, bool(word & HIGH_RESOLUTION_BIT))

    def describe(self) -> str:
        return f"{self.speed} µm/s {'high' if self.high else 'low'} (word {self.word:04X})"


#: the fastest `V` speed in µm/s (MP-38): at low resolution by controller model, at high resolution
MAX_SPEED_LOW_UM_S = {"mp285": 6550, "mp285a": 3000}
MAX_SPEED_HIGH_UM_S = 1310


@dataclass(frozen=True)
class SpeedLimits:
    """The fastest speed in µm/s at low and at high resolution (MP-38)."""

    low: int
    high: int = MAX_SPEED_HIGH_UM_S

    @classmethod
    def of_model(cls, model: str) -> SpeedLimits:
        """A controller model's documented limits (`mp285` or `mp285a`)."""
        return cls(MAX_SPEED_LOW_UM_S[model])

    def limit(self, high: bool) -> int:
        return self.high if high else self.low

    def clamp(self, velocity: Velocity) -> Velocity:
        """The velocity in force after `V`: a speed over its resolution's limit is reduced to the
        limit (MP-39)."""
        return Velocity(min(velocity.speed, self.limit(velocity.high)), velocity.high)
