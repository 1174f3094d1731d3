"""Explaining (a traffic log is kept) never changes what a device does: the same input gives the same
bytes at the same instants with and without it. While it explains, every emission carries a summary
and the MP-285 accounts for every byte it received on a clean line (design rule 11)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable

from hypothesis import given
from hypothesis import strategies as st

from emulator.device import FRAME, GARBLED, LOST, STRAY, Emission, LineSettings
from emulator.profiles.profile import load_profile
from tests.support.fuzz import fuzz_settings
from tests.unit.mp285.harness import Bench
from tests.unit.mp285.test_mp285_fuzz import KNOB_SETS, chunks, feed, recover_and_query
from tests.unit.ms2000.conftest import Harness
from tests.unit.ms2000.test_fuzz import lines

FUZZ = fuzz_settings(40)
HOSTS = [None, (19200, "none", 1), (4800, "none", 1), (9600, "even", 1)]


def recording(take: Callable[[], list[Emission]], into: list[Emission]) -> Callable[[], list[Emission]]:
    def wrapped() -> list[Emission]:
        out = take()
        into.extend(out)
        return out

    return wrapped


def mp285_run(stream: list, knobs: int, host: tuple | None, explain: bool) -> tuple[Bench, list, list]:
    overrides = {"knobs": KNOB_SETS[knobs]}
    if host is None:
        bench = Bench(overrides=overrides)
    else:
        baud, parity, stop = host
        bench = Bench(overrides=overrides, host=LineSettings(baud, 8, parity, stop, False, False))
    bench.device.explain = explain
    emitted: list[Emission] = []
    bench.device.take_output = recording(bench.device.take_output, emitted)  # type: ignore[method-assign]
    feed(bench, stream)
    bench.settle(1.0)
    return bench, bench.emissions(), emitted


@FUZZ
@given(chunks, st.sampled_from(range(len(KNOB_SETS))), st.sampled_from(HOSTS))
def test_mp285_explaining_changes_nothing(stream: list, knobs: int, host: tuple | None) -> None:
    _, plain, _ = mp285_run(stream, knobs, host, explain=False)
    bench, explained, emitted = mp285_run(stream, knobs, host, explain=True)
    assert explained == plain
    assert all(e.summary for e in emitted)
    assert {n.kind for n in bench.device.take_rx_notes()} <= {FRAME, GARBLED, LOST, STRAY}


@FUZZ
@given(chunks, st.sampled_from(range(len(KNOB_SETS))), st.booleans())
def test_mp285_notes_account_for_every_byte_received(stream: list, knobs: int, usb: bool) -> None:
    """On a clean line each received byte is in one note once the controller is back in command
    position with nothing outstanding (bytes held during a move are noted when replayed, MP-52),
    on a USB port without RTS/CTS too (bytes lost to the receive register, MP-7)."""
    if usb:
        bench = Bench("mp285a", {"knobs": KNOB_SETS[knobs]}, LineSettings(9600, None, None, 1, False, False))
    else:
        bench = Bench(overrides={"knobs": KNOB_SETS[knobs]})
    device = bench.device
    device.explain = True
    received: Counter[int] = Counter()
    receive = device.receive

    def counting(data: bytes, now: float, channel: str = "main") -> None:
        received.update(data)
        receive(data, now, channel)

    device.receive = counting  # type: ignore[method-assign]
    feed(bench, stream)
    recover_and_query(bench, power_cycle_if_stuck=usb)
    noted: Counter[int] = Counter()
    for note in device.take_rx_notes():
        noted.update(note.data)
    assert noted == received


def ms2000_run(stream: list[tuple[bytes, int]], garbled: bool, explain: bool) -> list[Emission]:
    h = Harness(load_profile("ms2000"))
    h.dev.explain = explain
    emitted: list[Emission] = []
    h.dev.take_output = recording(h.dev.take_output, emitted)  # type: ignore[method-assign]
    if garbled:
        h.input("host_line", baud=19200)
    for data, chunk in stream:
        h.send(data, chunk)
        h.wait(0.05)
    h.wait(2.0)
    assert all(e.summary for e in emitted) == explain or not emitted
    return emitted


ms2000_stream = st.lists(
    st.tuples(
        st.one_of(lines.map(lambda text: text.encode("latin-1") + b"\r"), st.binary(max_size=8)),
        st.integers(1, 5),
    ),
    max_size=8,
)


@FUZZ
@given(ms2000_stream, st.booleans())
def test_ms2000_explaining_changes_nothing(stream: list[tuple[bytes, int]], garbled: bool) -> None:
    explained = ms2000_run(stream, garbled, explain=True)
    plain = ms2000_run(stream, garbled, explain=False)
    assert [(e.due, e.data, e.kind) for e in explained] == [(e.due, e.data, e.kind) for e in plain]
