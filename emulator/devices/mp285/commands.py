"""What the MP-285 does with each complete item the frame parser yields (docs/mp285.md §2 ... §10).

`TABLE` maps each command byte to its row of the protocol's command table (name, frame length, reply
length: protocols.mp285 `COMMANDS`, which the frame parser delimits by), its handler and whether
it is a query (`c`, `s`: answered at once even while a move is outstanding, MP-51, MP-52). A handler
runs when the frame's last byte is processed, at `t`, with the device in IDLE or PAUSED, or (queries
only) with a move outstanding.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from emulator.devices.mp285.motion import Program
from protocols import mp285 as proto
from protocols.mp285 import BadFrame, BufferOverrun, CtrlC, ErrorCode, Frame, Item, StrayTerminator

if TYPE_CHECKING:
    from emulator.devices.mp285.model import Mp285Device

#: `handler(device, command, t)`; each handler takes its own command dataclass
Handler = Callable[["Mp285Device", Any, float], None]


@dataclass(frozen=True)
class Entry:
    spec: proto.CommandSpec
    handler: Handler
    query: bool = False


def get_position(dev: Mp285Device, command: proto.GetPosition, t: float) -> None:
    dev.send(t, proto.encode_position(*dev.reported(t)))  # MP-35


def move(dev: Mp285Device, command: proto.Move, t: float) -> None:
    target = dev.stage.move_target((command.x, command.y, command.z), dev.relative, dev.velocity.high)
    if target is None:
        dev.error(t, ErrorCode.BAD_COMMAND)  # MP-36 error4
        return
    dev.start_run(t, target, None)


def set_velocity(dev: Mp285Device, command: proto.SetVelocity, t: float) -> None:
    velocity = command.velocity  # MP-37
    over = velocity.speed > dev.speed_limits.limit(velocity.high)  # MP-38
    if over and dev.knobs.velocity_over_limit == "error4":  # MP-39
        dev.error(t, ErrorCode.BAD_COMMAND)
        return
    dev.velocity = dev.speed_limits.clamp(velocity)  # MP-39 clamp, MP-61
    dev.send(t, b"\r")


def set_origin(dev: Mp285Device, command: proto.SetOrigin, t: float) -> None:
    dev.stage.origin = dev.stage.physical  # MP-32
    dev.send(t, b"\r")


def absolute(dev: Mp285Device, command: proto.Absolute, t: float) -> None:
    dev.relative = False  # MP-33
    dev.send(t, b"\r")


def relative(dev: Mp285Device, command: proto.Relative, t: float) -> None:
    dev.relative = True  # MP-33
    dev.send(t, b"\r")


def refresh(dev: Mp285Device, command: proto.Refresh, t: float) -> None:
    dev.refresh_display()  # MP-74
    dev.send(t, b"\r")


def reset(dev: Mp285Device, command: proto.Reset, t: float) -> None:
    dev.soft_reset(t, deaf=True)  # MP-55 ... MP-58


def get_status(dev: Mp285Device, command: proto.GetStatus, t: float) -> None:
    dev.send(t, dev.status_block().reply())  # MP-60


def download(dev: Mp285Device, command: proto.Download, t: float) -> None:
    lenient = dev.knobs.program_vector_types == "lenient"  # MP-67
    valid = all(v.is_move or v.is_pause or (lenient and v.descriptor) for v in command.vectors)
    if not 1 <= command.program <= proto.MAX_PROGRAM or not valid:
        dev.error(t, ErrorCode.BAD_COMMAND)
        return
    dev.programs[command.program] = command.vectors  # MP-66
    dev.send(t, b"\r")


def execute(dev: Mp285Device, command: proto.Execute, t: float) -> None:
    if not 1 <= command.program <= proto.MAX_PROGRAM:
        dev.error(t, ErrorCode.BAD_COMMAND)  # MP-72
        return
    dev.take_paused()  # MP-71: a new k abandons a paused program
    vectors = dev.programs.get(command.program)
    if vectors is None:
        dev.send(t, b"\r")  # MP-72: never downloaded
        return
    dev.continue_program(t, Program(command.program, vectors))  # MP-68


def upload(dev: Mp285Device, command: proto.Upload, t: float) -> None:
    if not 1 <= command.program <= proto.MAX_PROGRAM:
        dev.error(t, ErrorCode.BAD_COMMAND)
        return
    dev.send(t, proto.encode_program(dev.programs.get(command.program, ())))  # MP-72


def continue_(dev: Mp285Device, command: proto.Continue, t: float) -> None:
    program = dev.take_paused()
    if program is None:
        dev.send(t, b"\r")  # MP-70
        return
    if not dev.knobs.k_reply_at_pause:
        dev.send(t, b"\r")  # MP-68: e answers at once, k's reply comes at the end
    dev.continue_program(t, program)


def _entry(command: type[proto.Command], handler: Handler, query: bool = False) -> tuple[int, Entry]:
    return command.BYTE, Entry(proto.COMMANDS[command.BYTE], handler, query)


TABLE: dict[int, Entry] = dict(
    (
        _entry(proto.GetPosition, get_position, query=True),
        _entry(proto.Move, move),
        _entry(proto.SetVelocity, set_velocity),
        _entry(proto.SetOrigin, set_origin),
        _entry(proto.Absolute, absolute),
        _entry(proto.Relative, relative),
        _entry(proto.Refresh, refresh),
        _entry(proto.Reset, reset),
        _entry(proto.GetStatus, get_status, query=True),
        _entry(proto.Download, download),
        _entry(proto.Execute, execute),
        _entry(proto.Upload, upload),
        _entry(proto.Continue, continue_),
    )
)
QUERY_BYTES = tuple(byte for byte, entry in TABLE.items() if entry.query)


def run_item(dev: Mp285Device, item: Item, t: float) -> None:
    """One item of the frame parser, processed at `t`."""
    if isinstance(item, Frame):
        command = item.command
        TABLE[command.BYTE].handler(dev, command, t)
    elif isinstance(item, CtrlC):
        dev.take_paused()  # MP-71: abandons a paused program
        dev.send(t, b"\r")  # MP-49
    elif isinstance(item, StrayTerminator):
        if dev.knobs.stray_terminator_reply == "cr":  # MP-20
            dev.send(t, b"\r")
    elif isinstance(item, BadFrame):
        if item.error is not None:
            dev.error(t, item.error)  # MP-21, MP-22, MP-24
    elif isinstance(item, BufferOverrun):
        dev.error(t, ErrorCode.BUFFER_OVERRUN)  # MP-23
