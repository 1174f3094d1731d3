"""MS2000 host side: how a host writes a command line (`format_command`, `command_line`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from protocols.ms2000.framing import CR


def format_command(word: str, items: Mapping[str, float | None] | Sequence[str] = ()) -> str:
    """A host command line without its CR: `format_command("M", {"X": 1000})` -> `M X=1000`; a
    mapping value None asks `L?`, a sequence sends its items verbatim (`["X+", "Y?"]`)."""
    parts = [word]
    if isinstance(items, Mapping):
        for letter, value in items.items():
            parts.append(f"{letter}?" if value is None else f"{letter}={host_number(value)}")
    else:
        parts.extend(items)
    return " ".join(parts)


def command_line(word: str, items: Mapping[str, float | None] | Sequence[str] = ()) -> bytes:
    """`format_command` encoded, with its CR: `command_line("M", {"X": 1000})` -> `b"M X=1000\\r"`."""
    return format_command(word, items).encode("ascii") + CR


def host_number(value: float) -> str:
    """A number as the controller's own examples send it: integers bare, others to 6 decimals."""
    if float(value).is_integer():
        return str(int(value))
    return f"{value:.6f}"
