"""Sutter MP-285 / MP-285A external-control protocol: a pure codec (no I/O, no clock).

The wire format (docs/mp285.md): a command is one command byte, a fixed-length binary payload and a
CR; ^C (`03`) stands alone. Multi-byte values are little-endian, least significant byte first
(MP-11): positions are signed 32-bit microstep counts, the `V` word and status words unsigned 16-bit.
Every reply ends with CR and has a fixed length, so hosts must read by count (MP-10).

What is here, one concern per module, all re-exported from this package:
- `wire`: control bytes, reply lengths, little-endian helpers;
- `commands`: the command table (`COMMANDS`) and one dataclass per command with `encode()`;
- `parser`: `FrameParser`, an incremental frame parser fed arbitrary chunks, which yields `Frame`,
  `CtrlC`, `StrayTerminator`, `BadFrame` and `BufferOverrun` items and exposes its state (command
  position, inside a frame, discarding) so a device model can treat bytes during a move differently;
- `replies`, `status`, `vectors`, `errors`: reply encoders/decoders: positions, uploaded programs,
  the 32-byte `StatusBlock`, program vectors, error codes;
- `speed`, `units`: the `V` word (`Velocity`) and the speed limits (`SpeedLimits`), microstep/micrometre
  conversion;
- `summary`: one-line traffic summaries.

This package must not import from `emulator`: the client library and the conformance suite use it.
"""

from __future__ import annotations

from protocols.mp285.commands import (
    COMMANDS,
    Absolute,
    Command,
    CommandSpec,
    Continue,
    Download,
    Execute,
    GetPosition,
    GetStatus,
    Interrupt,
    Move,
    Refresh,
    Relative,
    Reset,
    SetOrigin,
    SetVelocity,
    Upload,
    decode_command,
    reply_length,
)
from protocols.mp285.errors import (
    ERROR_NAMES,
    ErrorCode,
    combine_errors,
    error_reply,
    error_text,
    is_error_code,
)
from protocols.mp285.parser import (
    DOWNLOAD_HEADER,
    BadFrame,
    BufferOverrun,
    CtrlC,
    Frame,
    FrameParser,
    Item,
    ParseState,
    StrayTerminator,
)
from protocols.mp285.replies import decode_position, decode_program, encode_position, encode_program
from protocols.mp285.speed import (
    HIGH_RESOLUTION_BIT,
    MAX_SPEED_HIGH_UM_S,
    MAX_SPEED_LOW_UM_S,
    SpeedLimits,
    Velocity,
)
from protocols.mp285.status import StatusBlock
from protocols.mp285.summary import describe_item, summarize_device
from protocols.mp285.units import (
    DEFAULT_Z_USTEPS_PER_UM,
    XY_USTEPS_PER_UM,
    axis_factors,
    round_half_away,
    step_fields,
    um_to_usteps,
    usteps_to_um,
)
from protocols.mp285.vectors import (
    MAX_PROGRAM,
    MAX_VECTORS,
    MOVE_DESCRIPTOR,
    PAUSE_DESCRIPTOR,
    VECTOR_LENGTH,
    Vector,
    pack_vectors,
    unpack_vectors,
)
from protocols.mp285.wire import (
    ACK_INTERRUPT,
    AXES,
    CR,
    CTRL_C,
    INT32_MAX,
    INT32_MIN,
    LF,
    POSITION_REPLY_LENGTH,
    STATUS_LENGTH,
    STATUS_REPLY_LENGTH,
    pack_u16,
    pack_xyz,
    unpack_u16,
    unpack_xyz,
)

__all__ = [
    "ACK_INTERRUPT",
    "AXES",
    "COMMANDS",
    "CR",
    "CTRL_C",
    "DEFAULT_Z_USTEPS_PER_UM",
    "DOWNLOAD_HEADER",
    "ERROR_NAMES",
    "HIGH_RESOLUTION_BIT",
    "INT32_MAX",
    "INT32_MIN",
    "LF",
    "MAX_PROGRAM",
    "MAX_SPEED_HIGH_UM_S",
    "MAX_SPEED_LOW_UM_S",
    "MAX_VECTORS",
    "MOVE_DESCRIPTOR",
    "PAUSE_DESCRIPTOR",
    "POSITION_REPLY_LENGTH",
    "STATUS_LENGTH",
    "STATUS_REPLY_LENGTH",
    "VECTOR_LENGTH",
    "XY_USTEPS_PER_UM",
    "Absolute",
    "BadFrame",
    "BufferOverrun",
    "Command",
    "CommandSpec",
    "Continue",
    "CtrlC",
    "Download",
    "ErrorCode",
    "Execute",
    "Frame",
    "FrameParser",
    "GetPosition",
    "GetStatus",
    "Interrupt",
    "Item",
    "Move",
    "ParseState",
    "Refresh",
    "Relative",
    "Reset",
    "SetOrigin",
    "SetVelocity",
    "SpeedLimits",
    "StatusBlock",
    "StrayTerminator",
    "Upload",
    "Vector",
    "Velocity",
    "axis_factors",
    "combine_errors",
    "decode_command",
    "decode_position",
    "decode_program",
    "describe_item",
    "encode_position",
    "encode_program",
    "error_reply",
    "error_text",
    "is_error_code",
    "pack_u16",
    "pack_vectors",
    "pack_xyz",
    "reply_length",
    "round_half_away",
    "step_fields",
    "summarize_device",
    "um_to_usteps",
    "unpack_u16",
    "unpack_vectors",
    "unpack_xyz",
    "usteps_to_um",
]
