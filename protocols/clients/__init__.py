"""Thin pyserial host libraries: `from protocols.clients import Mp285, MS2000`."""

from protocols.clients.errors import NoReply
from protocols.clients.mp285 import (
    BadCommand,
    BufferOverrun,
    FrameError,
    MoveInterrupted,
    MoveOutstanding,
    Mp285,
    Mp285Error,
    SpOverrun,
    UnexpectedReply,
)
from protocols.clients.ms2000 import (
    MS2000,
    Halted,
    MissingParameters,
    MS2000Error,
    OperationFailed,
    OutOfRange,
    TtlReportPort,
    UndefinedError,
    UnknownAxis,
    UnknownCommand,
)

__all__ = [
    "MS2000",
    "BadCommand",
    "BufferOverrun",
    "FrameError",
    "Halted",
    "MS2000Error",
    "MissingParameters",
    "MoveInterrupted",
    "MoveOutstanding",
    "Mp285",
    "Mp285Error",
    "NoReply",
    "OperationFailed",
    "OutOfRange",
    "SpOverrun",
    "TtlReportPort",
    "UndefinedError",
    "UnexpectedReply",
    "UnknownAxis",
    "UnknownCommand",
]
