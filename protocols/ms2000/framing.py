"""MS2000 reply framing: the CR LF or CR terminator and multi-line replies (MS-14…MS-16)."""

from __future__ import annotations

from collections.abc import Sequence

CR = b"\r"
CRLF = b"\r\n"


def terminator(cr_only: bool) -> bytes:
    """CR LF, or CR alone with `VB X` bit 3 (MS-14, MS-16)."""
    return CR if cr_only else CRLF


def frame(lines: Sequence[bytes], cr_only: bool = False) -> bytes:
    """A complete reply: lines separated by bare CR, then the terminator (MS-15)."""
    return CR.join(lines) + terminator(cr_only)


def split_lines(block: bytes) -> list[bytes]:
    """The lines of a multi-line reply (MS-15), terminator removed."""
    if block.endswith(CRLF):
        block = block[:-2]
    elif block.endswith(CR):
        block = block[:-1]
    return block.split(CR) if block else [b""]
