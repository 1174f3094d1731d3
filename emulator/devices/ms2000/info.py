"""Text reports: INFO (MS-106), BUILD X (MS-102) and the DUMP buffers (MS-108)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Protocol

from emulator.devices.ms2000.sections import INPUT_DEVICES
from emulator.devices.ms2000.status import move_stat
from protocols.ms2000 import BU_CMDS, BU_MOTOR_AXES, INFO_LEFT_WIDTH, fixed
from protocols.rounding import round_half_away

if TYPE_CHECKING:
    from emulator.devices.ms2000.axis import Axis
    from emulator.devices.ms2000.modules.moduleset import ModuleSet
    from emulator.devices.ms2000.schema import Ms2000Config
    from emulator.devices.ms2000.sections import Ms2000Knobs
    from emulator.devices.ms2000.settings import CardSettings

LABEL_WIDTH = 13
VALUE_WIDTH = 10


class Reported(Protocol):
    """All the reports read of their controller."""

    @property
    def cfg(self) -> Ms2000Config: ...

    @property
    def knobs(self) -> Ms2000Knobs: ...

    @property
    def card(self) -> CardSettings: ...

    @property
    def axes(self) -> Sequence[Axis]: ...

    @property
    def modules(self) -> ModuleSet:
        """Their `BU X` lines."""

    def manual_inverted(self, axis: Axis) -> bool: ...

    def left_char(self, axis: Axis, t: float) -> str: ...


def _item(label: str, value: str, suffix: str = "") -> str:
    return f"{label:<{LABEL_WIDTH}}:{value:>{VALUE_WIDTH}}{suffix}"


def _row(left: str, right: str) -> str:
    return f"{left:<{INFO_LEFT_WIDTH}}{right}"


def info_block(controller: Reported, axis: Axis, t: float) -> list[str]:
    """The INFO report of one axis: 21 rows of two items, left item padded to 33 characters."""
    s = axis.s
    c = s.counts_per_mm
    servo_ms = controller.cfg.servo_ms
    steps = max(1, round_half_away(s.accel_ms / servo_ms))
    vmax_enc = math.floor(min(s.speed, axis.max_speed) * c * servo_ms / 1000)
    dv_enc = vmax_enc // steps
    pc_tag = "[PC]" if controller.knobs.info_fix_pc_tag else "[PC}"
    position = axis.pos(t)
    velocity = axis.traj.vel(t)
    vmax = axis.max_speed * c
    dac = 128 + round(127 * max(-1.0, min(1.0, velocity / vmax))) if vmax else 128
    settle = fixed(controller.knobs.landing_ms, 0)
    sign = -1 if controller.manual_inverted(axis) else 1
    return [
        _row(
            f"{'Axis Name':<{LABEL_WIDTH}}:  {axis.letter}",
            f"{'Limits Status':<{LABEL_WIDTH}}: {controller.left_char(axis, t)}",
        ),
        _row(
            _item("Input Device", INPUT_DEVICES.get(s.input_device, "NONE"), " [J]"),
            _item("In_Dev Sign", str(sign)),
        ),
        _row(
            _item("Max Lim", fixed(axis.user_of_machine_mm(axis.auto.soft_upper), 3), " [SU]"),
            _item("Min Lim", fixed(axis.user_of_machine_mm(axis.auto.soft_lower), 3), " [SL]"),
        ),
        _row(_item("Ramp Time", str(s.accel_ms), " (ms)[AC]"), _item("Max Ramp Stps", str(steps))),
        _row(
            _item("Run Speed", fixed(min(s.speed, axis.max_speed), 5), "(mm/s)[S]"),
            _item("vmax_enc", str(vmax_enc)),
        ),
        _row(
            _item("Servo Lp Time", str(servo_ms), " (ms)"),
            _item("Ramp Length", str(dv_enc * steps * (steps - 1)), " (enc)"),
        ),
        _row(_item("dv_enc", str(dv_enc)), _item("LL Axis ID", str(s.ll_id))),
        _row(
            _item("Drift Error", fixed(s.drift_error, 6), " (mm)[E]"),
            _item("enc_drift_err", str(math.floor(s.drift_error * c))),
        ),
        _row(
            _item("Finish Error", fixed(s.finish_error, 6), f" (mm){pc_tag}"),
            _item("enc_finsh_err", str(max(1, math.floor(s.finish_error * c)))),
        ),
        _row(
            _item("Backlash", fixed(s.backlash, 6), " (mm)[B]"),
            _item("enc_backlash", str(math.floor(s.backlash * c))),
        ),
        _row(_item("Kp", str(s.kp), " [KP]"), _item("Ki", str(s.ki), " [KI]")),
        _row(_item("Kv", str(s.kv), " [KV]"), _item("Kd", str(s.kd), " [KD]")),
        _row(
            _item("Axis Enable", "3" if axis.enabled else "0", " [MC]"),
            _item("Motor Enable", "1" if axis.motor_on(t) else "0"),
        ),
        _row(
            _item("CMD_stat", "MOVING" if axis.busy(t) else "NO_MOVE"), _item("Move_stat", move_stat(axis, t))
        ),
        _row(
            _item("Current pos", fixed(axis.user_mm_of(position), 4), " (mm)"),
            _item("enc position", fixed(axis.physical(t), 0)),
        ),
        _row(
            _item("Target pos", fixed(axis.user_mm_of(axis.target), 4), " (mm)"),
            # the encoder's target includes planar correction; "Target pos" is in plane coordinates
            _item("enc target", fixed(axis.physical_target(t), 0)),
        ),
        _row(_item("enc pos error", fixed(axis.target - position, 0)), _item("EEsum", "0")),
        _row(_item("Lst Stle Time", settle, " (ms)"), _item("Av Settle Tim", settle, " (ms)")),
        _row(
            _item("Home position", fixed(axis.user_of_machine_mm(axis.auto.home), 2), " (mm)"),
            _item("Motor Signal", str(dac), " (DAC)"),
        ),
        _row(_item("mm/sec/DAC_ct", fixed(s.dac, 5), " [D]"), _item("Enc Cnts/mm", fixed(c, 2), " [C]")),
        _row(
            _item("Wait Time", str(s.wait_ms), " [WT]"),
            _item("Button Enable", str(controller.card.button_enable), " [BE]"),
        ),
    ]


def build_lines(controller: Reported) -> list[str]:
    """BU X (MS-102): build name, axes, command letters, boot loader, hardware, one line per module."""
    cfg = controller.cfg
    lines = [
        cfg.build_name,
        " ".join([BU_MOTOR_AXES, *(a.letter for a in controller.axes)]),
        f"{BU_CMDS} {cfg.cmd_letters}",
        cfg.bootldr,
        cfg.hdwr,
    ]
    return [*lines, *controller.modules.bu_lines()]
