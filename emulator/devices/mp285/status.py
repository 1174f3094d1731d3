"""What the MP-285 shows of itself: the 32-byte status block of the `s` reply (docs/mp285.md §9,
MP-60 ... MP-65) and the front-panel display (§11, MP-74, MP-75)."""

from __future__ import annotations

import dataclasses

from emulator.devices.mp285.motion import Xyz
from emulator.devices.mp285.schema import Mp285Controller, Mp285Knobs, Mp285Stage
from protocols import mp285 as proto
from protocols.mp285 import StatusBlock, Velocity

#: FLAGS bit 4: the ROE was last turned the negative way (MP-79); bit 5: REL_ABS_F (MP-64)
FLAGS_ROE_NEGATIVE = 0x10
FLAGS_REL_ABS = 0x20
#: FLAGS_2 bit 2: high resolution, mirrors XSPEED bit 15 (MP-62)
FLAGS_2_HIGH_RESOLUTION = 0x04


class Status:
    """The profile's status template (MP-65) with the live fields filled in."""

    def __init__(self, controller: Mp285Controller, stage: Mp285Stage, knobs: Mp285Knobs) -> None:
        self.template = StatusBlock.unpack(bytes.fromhex(controller.status_template))
        #: FLAGS bit 4, set by the last ROE turn (MP-79); the template's at power-on (MP-76)
        self.roe_negative = self.template.roe_negative
        self._step_fields = proto.step_fields(
            proto.XY_USTEPS_PER_UM[stage.device_type], controller.step_fields_format
        )  # MP-63
        self._version: int = controller.firmware_version
        self._bit5_tracks_mode: bool = knobs.flags_bit5_tracks_move_mode
        self._bit5_relative_is_set: bool = knobs.flags_bit5_relative_is_set

    def power_on(self) -> None:
        """MP-76: the profile's status, ROE direction included."""
        self.roe_negative = self.template.roe_negative

    def block(self, relative: bool, velocity: Velocity) -> StatusBlock:
        """MP-60 ... MP-64: FLAGS bits 4 and 5, FLAGS_2 bit 2, STEP fields, XSPEED and VERSION."""
        template = self.template
        flags = template.flags & ~FLAGS_ROE_NEGATIVE | (FLAGS_ROE_NEGATIVE if self.roe_negative else 0)
        if self._bit5_tracks_mode:
            set_bit = relative == self._bit5_relative_is_set
            flags = flags & ~FLAGS_REL_ABS | (FLAGS_REL_ABS if set_bit else 0)
        high = FLAGS_2_HIGH_RESOLUTION if velocity.high else 0
        step_div, step_mul = self._step_fields
        return dataclasses.replace(
            template,
            flags=flags,
            flags_2=template.flags_2 & ~FLAGS_2_HIGH_RESOLUTION | high,
            step_div=step_div,
            step_mul=step_mul,
            xspeed=velocity.word,
            version=self._version,
        )


class Display:
    """The vacuum-fluorescent display as two text lines (MP-75)."""

    def __init__(self, factors: tuple[float, ...]) -> None:
        self._factors = factors
        self.lines = ["", ""]

    def refresh(self, reported: Xyz) -> None:
        """MP-74, MP-75: line 1 shows the coordinates in µm as of now (never during a move); line 2
        is cleared."""
        self.lines = [
            " ".join(
                f"{a}:{p / f:+.2f}" for a, p, f in zip(proto.AXES, reported, self._factors, strict=True)
            ),
            "",
        ]

    def show_error(self, code: int) -> None:
        """MP-75: line 2 shows the error; an ORed '8' shows the other code, as the unit shows '4'
        for '<' (MP-19)."""
        shown = code & ~0x08 if 0x39 <= code <= 0x3C else code
        self.lines[1] = f"ERR {chr(shown)}"
