"""MP-285 traffic summaries: one line per parser item or per block of device bytes."""

from __future__ import annotations

from protocols.mp285.errors import error_text, is_error_code
from protocols.mp285.parser import BadFrame, CtrlC, Frame, Item, StrayTerminator
from protocols.mp285.replies import decode_program
from protocols.mp285.status import StatusBlock
from protocols.mp285.vectors import VECTOR_LENGTH
from protocols.mp285.wire import ACK_INTERRUPT, CR, POSITION_REPLY_LENGTH, STATUS_REPLY_LENGTH, unpack_xyz


def describe_item(item: Item) -> str:
    """One line for an item of the frame parser, e.g. `m X=1200 Y=-40 Z=0 (µsteps)`."""
    if isinstance(item, Frame):
        return item.command.describe()
    if isinstance(item, CtrlC):
        return "^C"
    if isinstance(item, StrayTerminator):
        return "stray CR" if item.byte == CR else "stray LF"
    if isinstance(item, BadFrame):
        owed = "no reply owed" if item.error is None else f"error '{chr(item.error)}' owed"
        return f"CR ending a bad frame ({owed})"
    return "buffer overrun: error '2'"


def _hex(data: bytes, limit: int = 48) -> str:
    text = data[:limit].hex(" ").upper()
    return text + (" …" if len(data) > limit else "")


def summarize_device(data: bytes, to: str | None = None) -> str:
    """One line for bytes the device sent, interpreted by length and content (replies carry no
    type), e.g. `reply: position X=… Y=… Z=…` or `error '4' bad command`; given the command they
    answer, `to`, e.g. `reply to c: position X=… Y=… Z=…`."""
    text = _describe_device(data)
    return text if to is None else f"reply to {to}: {text.removeprefix('reply: ')}"


def _describe_device(data: bytes) -> str:
    if data == b"\r":
        return "reply: CR (done)"
    if data == bytes((ACK_INTERRUPT,)):
        return "reply: '=' (interrupt acknowledged)"
    if len(data) == 2 and data[1] == CR and is_error_code(data[0]):
        return f"error '{chr(data[0])}' {error_text(data[0])}"
    if len(data) == POSITION_REPLY_LENGTH and data[-1] == CR:
        x, y, z = unpack_xyz(data[:12])
        return f"reply: position X={x} Y={y} Z={z} (µsteps)"
    if len(data) == STATUS_REPLY_LENGTH and data[-1] == CR:
        return f"reply: status {StatusBlock.unpack(data).describe()}"
    if len(data) >= 2 and data[-1] == CR and len(data) == 2 + VECTOR_LENGTH * data[0]:
        vectors = decode_program(data)
        return f"reply: program of {len(vectors)} vector(s): {', '.join(v.describe() for v in vectors)}"
    return f"{len(data)} byte(s): {_hex(data)}"
