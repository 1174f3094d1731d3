"""Settings commands, argument grammar, reply shapes and errors (§2.4, §3, §4, §6.8) beyond the test
vectors, which run in tests/conformance/ms2000 (TV-11…TV-25, TV-39…TV-46, TV-57, TV-58, TV-91,
TV-111, TV-112, TV-114)."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from tests.unit.ms2000.conftest import Harness

ACK = b":A\r\n"


def test_malformed_item_is_undefined_error_ms39(ms: Harness) -> None:
    assert ms.cmd("S 5=3") == b":N-6\r\n"
    assert ms.cmd("S 5=3 Q=1") == b":N-2\r\n"


@pytest.mark.parametrize("word", ["S", "B", "M", "R", "!", "SS", "AC", "LD", "I", "AZ", "RS"])
def test_commands_needing_items_ms31(ms: Harness, word: str) -> None:
    assert ms.cmd(word) == b":N-3\r\n"


@pytest.mark.parametrize("word", ["Z", "V", "CD", "N", "BU", "DU", "TTL", "LCD", "UN", "/", "RM"])
def test_bare_forms_with_their_own_meaning_ms31(ms: Harness, word: str) -> None:
    assert not ms.cmd(word).startswith(b":N")


def test_vb_silent_ms109(make: Callable[..., Harness]) -> None:
    h = make(overrides={"knobs": {"vb_silent": True}})
    assert h.cmd("VB Z=1") == b""
    assert h.cmd("VB Z?") == b":A Z=1\r\n"


def test_z2b_renames_after_save_and_reset_ms115(ms: Harness) -> None:
    assert ms.cmd("Z2B Z=70") == ACK
    assert ms.cmd("Z2B Y=88") == b":N-4\r\n"
    ms.cmd("SS Z")
    ms.cmd("~")
    assert ms.cmd("W F") == b":A 0\r\n"
    assert ms.cmd("W Z") == b":N-2\r\n"
    assert b"Motor Axes: X Y F\r" in ms.cmd("BU X")


def test_other_stored_settings_read_back_ms97_ms61_ms62(ms: Harness) -> None:
    for command, reply in [
        ("MA X=2", ACK),
        ("MA X?", b":A X=2\r\n"),
        ("RU X=2.5", ACK),
        ("RU X?", b":A X=2.500000\r\n"),
        ("C X?", b":A X=45396.000000\r\n"),
        ("CCA X=5 Y=2 Z=3", ACK),
        ("CCA X? Y? Z?", b":A X=5 Y=2 Z=3\r\n"),
        ("UM Y?", b":A Y=10000.000000\r\n"),
        ("WT X=5 Y=6", ACK),
        ("WT Y? X?", b":X=5 Y=6 A\r\n"),
        ("B Z?", b":Z=0.010000 A\r\n"),
    ]:
        assert ms.cmd(command) == reply, command
