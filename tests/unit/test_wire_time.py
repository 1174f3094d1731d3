"""Pacing arithmetic: character times and the per-direction pacer."""

from __future__ import annotations

import pytest

from emulator.device import LineSettings
from emulator.wire_time import Pacer, bits_per_char, char_time, mismatches, settings_char_time


def test_character_times() -> None:
    assert bits_per_char() == 10
    assert bits_per_char(8, "even", 2) == 12
    assert char_time(9600) == pytest.approx(1.0417e-3, rel=1e-4)
    assert char_time(9600, 8, "none", 1.5) == pytest.approx(10.5 / 9600)
    # 100 bytes at 9600 8N1 take 104.17 ms on the wire (the integration test checks the same live)
    assert 100 * char_time(9600) == pytest.approx(0.10417, rel=1e-3)


def test_unseen_settings_come_from_the_device() -> None:
    device = LineSettings(9600, 8, "even", 2)
    host = LineSettings(19200, None, None, 1)
    assert settings_char_time(host, device) == pytest.approx(11 / 19200)


def test_pacer_serialises_characters() -> None:
    pacer = Pacer(0.001)
    pacer.push(0.0, b"abc")
    pacer.push(0.0015, b"d")  # waits for the wire: starts at 0.003
    assert pacer.next_due() == pytest.approx(0.001)
    assert pacer.take_due(0.0005) == []
    assert pacer.take_due(0.0021) == [(pytest.approx(0.002), b"ab")]
    assert pacer.take_each_due(0.01) == [(pytest.approx(0.003), ord("c")), (pytest.approx(0.004), ord("d"))]
    assert pacer.wire_free == pytest.approx(0.004)
    assert len(pacer) == 0


def test_pacer_idle_gap_restarts_at_push_time() -> None:
    pacer = Pacer(0.001)
    pacer.push(0.0, b"a")
    pacer.push(1.0, b"b")
    assert pacer.take_due(2.0) == [(pytest.approx(0.001), b"a"), (pytest.approx(1.001), b"b")]


def test_fast_pacer_delivers_at_once() -> None:
    pacer = Pacer(0.0)
    pacer.push(5.0, b"hello")
    assert pacer.take_due(5.0) == [(5.0, b"hello")]


def test_mismatch_ignores_what_is_not_visible() -> None:
    device = LineSettings(9600, 8, "none", 1, False, False)
    assert mismatches(device, LineSettings(9600, None, None, 1, False, False)) == []
    assert mismatches(device, LineSettings(19200, None, None, 2, True, False)) == [
        "baud",
        "stop_bits",
        "rtscts",
    ]
