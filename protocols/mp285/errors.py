"""MP-285 error replies: the error digits, their names and ORed combinations (MP-19)."""

from __future__ import annotations

import enum

from protocols.mp285.wire import CR


class ErrorCode(enum.IntEnum):
    """Error reply digits. '8' may be ORed with another code (MP-19)."""

    SP_OVERRUN = 0x30
    FRAME = 0x31
    BUFFER_OVERRUN = 0x32
    BAD_COMMAND = 0x34
    MOVE_INTERRUPTED = 0x38


ERROR_NAMES = {
    ErrorCode.SP_OVERRUN: "SP overrun",
    ErrorCode.FRAME: "frame error",
    ErrorCode.BUFFER_OVERRUN: "buffer overrun",
    ErrorCode.BAD_COMMAND: "bad command",
    ErrorCode.MOVE_INTERRUPTED: "move interrupted",
}


def combine_errors(*codes: int) -> int:
    """OR error digits together: '8' | '4' = '<' (MP-19)."""
    result = 0
    for code in codes:
        result |= code
    return result


def is_error_code(byte: int) -> bool:
    """True for '0', '1', '2', '4', '8' and '8' ORed with one of '0'-'4' ('9', ':', ';', '<')."""
    return byte in ERROR_NAMES or 0x38 <= byte <= 0x3C


def error_text(code: int) -> str:
    """`bad command`, or `move interrupted + bad command` for an ORed code."""
    if code in ERROR_NAMES:
        return ERROR_NAMES[ErrorCode(code)]
    if 0x39 <= code <= 0x3C:
        other = code & ~0x08
        name = ERROR_NAMES.get(ErrorCode(other)) if other in ERROR_NAMES else f"'{chr(other)}'"
        return f"move interrupted + {name}"
    return f"unknown error {code:02X}"


def error_reply(code: int) -> bytes:
    """`<digit> 0D`."""
    return bytes((code, CR))
