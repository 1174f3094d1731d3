"""`HostLine.describe`: what `stage-emu view`, `ctl list` and log lines say about a host's line
settings, including those its transport does not show (issue "Hardening, round two")."""

from __future__ import annotations

from emulator.device import HostLine, LineSettings


def test_a_pty_host_says_which_settings_are_not_visible() -> None:
    """A PTY carries the baud rate, stop bits and flow control, not data bits or parity."""
    pty = HostLine(baud=9600, data_bits=None, parity=None, stop_bits=1, rtscts=True, xonxoff=False)
    assert pty.describe() == "9600 ??1 rtscts (data bits, parity not visible)"


def test_a_host_seen_in_full_is_the_compact_form() -> None:
    full = LineSettings(baud=19200, data_bits=7, parity="even", stop_bits=2, rtscts=False, xonxoff=True)
    assert full.describe() == "19200 7E2 xonxoff"


def test_a_host_that_shows_nothing_says_so() -> None:
    """A raw TCP client: no settings at all."""
    assert HostLine().describe() == "line settings not visible"


def test_a_partly_seen_host_names_each_missing_setting() -> None:
    assert HostLine(parity="odd").describe() == "? ?O? (baud, data bits, stop bits not visible)"
