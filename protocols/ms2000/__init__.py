"""ASI MS-2000 serial protocol: pure codec shared by the emulator and host-side clients.

No I/O, no clock and no emulator imports. It covers, one concern per module, all re-exported from
this package:
- `commands`: the command table (long names, shortcuts, owning firmware module) and command-word
  matching;
- `grammar`: the argument grammar (`L=v`, `L?`, `L+`, `L-`, bare `L`, bare numbers; prefixes before
  the key letter, spaces around `=`, missing value = 0);
- `host`: how a host writes a command line (`format_command`, `command_line`);
- `shapes`, `formats`, `errors`, `framing`: reply shapes and number formats, the error table,
  terminators and multi-line replies;
- `replies`, `reports`: reply classification for host programs (`parse_reply`), the INFO and BU X
  layouts;
- `lowlevel`: the low-level binary mode (control sequences, frames, 24-bit numbers);
- `summary`: one-line traffic summaries.

Rule IDs (MS-n) refer to the project's MS-2000 behaviour specification; docs/ms2000.md explains them.
"""

from __future__ import annotations

from protocols.ms2000.commands import (
    ARRAY,
    AUTOFOCUS,
    BASE,
    BY_KEY,
    COMMANDS,
    CRISP,
    DLED,
    INO_INT,
    LED_DIMMER,
    RING_BUFFER,
    SCAN,
    SPLIT_CHARS,
    TRACKING,
    CommandSpec,
    lookup,
)
from protocols.ms2000.errors import ERROR_TEXT, ErrorCode, error_reply, error_text
from protocols.ms2000.formats import Fmt, f3, f6, fixed, format_value, integer, round_decimals, where
from protocols.ms2000.framing import CR, CRLF, frame, split_lines, terminator
from protocols.ms2000.grammar import (
    CommandLine,
    Item,
    Kind,
    is_blank,
    normalize,
    parse_items,
    split_command,
)
from protocols.ms2000.host import command_line, format_command, host_number
from protocols.ms2000.lowlevel import (
    CONTROL,
    INT24_MAX,
    LL_READ_N,
    LL_REPLY_LENGTH,
    LL_TERMINATOR,
    LL_WRITES,
    LLCommand,
    LLFrame,
    LLFrameDecoder,
    decode_int24,
    encode_int24,
    encode_ll_frame,
)
from protocols.ms2000.replies import ParsedReply, ReplyKind, parse_reply
from protocols.ms2000.reports import BU_CMDS, BU_MOTOR_AXES, INFO_LEFT_WIDTH, parse_info
from protocols.ms2000.shapes import (
    QUERY_SHAPES,
    SHAPE_NAMES,
    TRAILING_SPACE_SHAPES,
    Shape,
    ack,
    format_items,
    query_shape,
)
from protocols.ms2000.summary import shown, summarize_line

__all__ = [
    "ARRAY",
    "AUTOFOCUS",
    "BASE",
    "BU_CMDS",
    "BU_MOTOR_AXES",
    "BY_KEY",
    "COMMANDS",
    "CONTROL",
    "CR",
    "CRISP",
    "CRLF",
    "DLED",
    "ERROR_TEXT",
    "INFO_LEFT_WIDTH",
    "INO_INT",
    "INT24_MAX",
    "LED_DIMMER",
    "LL_READ_N",
    "LL_REPLY_LENGTH",
    "LL_TERMINATOR",
    "LL_WRITES",
    "QUERY_SHAPES",
    "RING_BUFFER",
    "SCAN",
    "SHAPE_NAMES",
    "SPLIT_CHARS",
    "TRACKING",
    "TRAILING_SPACE_SHAPES",
    "CommandLine",
    "CommandSpec",
    "ErrorCode",
    "Fmt",
    "Item",
    "Kind",
    "LLCommand",
    "LLFrame",
    "LLFrameDecoder",
    "ParsedReply",
    "ReplyKind",
    "Shape",
    "ack",
    "command_line",
    "decode_int24",
    "encode_int24",
    "encode_ll_frame",
    "error_reply",
    "error_text",
    "f3",
    "f6",
    "fixed",
    "format_command",
    "format_items",
    "format_value",
    "frame",
    "host_number",
    "integer",
    "is_blank",
    "lookup",
    "normalize",
    "parse_info",
    "parse_items",
    "parse_reply",
    "query_shape",
    "round_decimals",
    "shown",
    "split_command",
    "split_lines",
    "summarize_line",
    "terminator",
    "where",
]
