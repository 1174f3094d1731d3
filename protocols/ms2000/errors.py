"""MS2000 errors (§4): the `:N-<code>` error codes and their meanings (MS-39)."""

from __future__ import annotations

from enum import IntEnum


class ErrorCode(IntEnum):
    UNKNOWN_COMMAND = 1
    BAD_AXIS = 2
    MISSING_PARAMETERS = 3
    OUT_OF_RANGE = 4
    FAILED = 5
    UNDEFINED = 6
    HALTED = 21


#: the meaning of each error code (MS-39)
ERROR_TEXT: dict[int, str] = {
    ErrorCode.UNKNOWN_COMMAND: "unknown command",
    ErrorCode.BAD_AXIS: "unrecognised axis parameter",
    ErrorCode.MISSING_PARAMETERS: "missing parameters",
    ErrorCode.OUT_OF_RANGE: "parameter out of range",
    ErrorCode.FAILED: "operation failed",
    ErrorCode.UNDEFINED: "undefined error",
    ErrorCode.HALTED: "serial command halted by HALT",
}


def error_text(code: int) -> str:
    """The meaning of `:N-<code>`; `error` for a code outside the table."""
    return ERROR_TEXT.get(code, "error")


def error_reply(code: int) -> str:
    return f":N-{int(code)}"
