"""MS2000 traffic summaries: bytes and command lines as one line of the traffic log."""

from __future__ import annotations

from protocols.ms2000.grammar import is_blank, split_command


def shown(data: bytes) -> str:
    """Bytes for the traffic log: printable text with escapes (`:A 0 0 \\r\\n`), else hex."""
    text = data.decode("latin-1")
    if not all(32 <= ord(ch) < 127 or ch in "\r\n\t" for ch in text):
        return f"binary {data.hex(' ')}"
    return text.replace("\r", "\\r").replace("\n", "\\n").replace("\t", "\\t")


def summarize_line(line: bytes) -> str:
    """A command line (without its CR) with its command spelled out: `M X=1000 [MOVE]`."""
    text = line.decode("latin-1")
    if is_blank(text):
        return "blank line"
    spec = split_command(text).spec
    return f"{shown(line)} [{spec.name if spec else '?'}]"
