"""Hypothesis: arbitrary command lines and arbitrary bytes in arbitrary chunks never raise, produce
only reply forms the specification allows, and leave a controller that answers `W X` correctly
(after `0xFF 'A'` to leave low-level mode, MS-119)."""

from __future__ import annotations

import re

from hypothesis import given
from hypothesis import strategies as st

from emulator.profiles.profile import load_profile
from protocols import ms2000 as p
from tests.support.fuzz import fuzz_settings
from tests.unit.ms2000.conftest import Harness

PROFILE = load_profile("ms2000")
FUZZ = fuzz_settings(150)
WORDS = sorted({w for spec in p.COMMANDS for w in spec.words()} | {"FOO", "!X", "\\junk", ""})
ALLOWED_ERRORS = {b"1", b"2", b"3", b"4", b"5", b"6", b"21"}
#: what a reply line may look like: an error, `:A…`, value-first or colon forms, N/B, bare text
REPLY_LINE = re.compile(rb"(:N-\d+|:A.*|:[A-Z_]+=.* A|[A-Z_]+=.* :A|[NB]|[ -~]*)", re.S)

letters = st.sampled_from("XYZFTRMQxyz")
numbers = st.one_of(
    st.integers(-3_000_000, 3_000_000).map(str),
    st.floats(-1e6, 1e6, allow_nan=False).map(lambda v: f"{v:.6f}"),
    st.sampled_from(["", "abc", "1e3", ".5e1", "-0", "1e400", "99999999999"]),
)
items = st.one_of(
    st.tuples(letters, numbers).map(lambda lv: f"{lv[0]}={lv[1]}"),
    st.tuples(letters, st.sampled_from("?+-")).map("".join),
    letters,
    numbers,
    st.text(st.characters(min_codepoint=1, max_codepoint=126, exclude_characters="\r\xff"), max_size=6),
)
lines = st.tuples(st.sampled_from(WORDS), st.lists(items, max_size=5)).map(
    lambda word_items: " ".join([word_items[0], *word_items[1]])
)


def _check_replies(data: bytes) -> None:
    """Every complete line of output is an allowed form; errors carry a known code (MS-39, MS-40)."""
    for raw in re.split(rb"\r\n|\r", data):
        line = raw.lstrip(b"\n")
        if line.startswith(b":N-"):
            assert line[3:] in ALLOWED_ERRORS, data
        elif not line.startswith(b":A"):  # RDSBYTE replies carry raw bytes after `:A`
            assert REPLY_LINE.fullmatch(line), data


def _recovers(h: Harness) -> None:
    """Leave low-level mode, end any partial line, let blocking commands finish, then `W X`."""
    h.send(b"\xffA\r")
    h.wait(1.0)
    if h.get("mode") == "silent":
        h.input("power_cycle")
    h.output()
    reply = h.cmd("W X")
    axis = h.dev.axis_named("X")
    terminator = b"\r" if h.dev.card.vb_flags & 8 else b"\r\n"
    if axis is None:
        assert reply.endswith(b":N-2" + terminator)
    else:
        assert reply.endswith(f":A {h.dev.where(axis.units(h.t))}".encode() + terminator), reply


@FUZZ
@given(st.lists(lines, max_size=12))
def test_arbitrary_command_lines(batch: list[str]) -> None:
    h = Harness(PROFILE)
    for line in batch:
        out = h.send(line.encode("latin-1") + b"\r")
        assert not out or out.endswith((b"\r", b"\r\n")), out
        _check_replies(out)
    h.wait(0.5)
    _check_replies(h.output())
    _recovers(h)


@FUZZ
@given(st.binary(max_size=300), st.integers(1, 40))
def test_arbitrary_bytes_any_chunking(data: bytes, chunk: int) -> None:
    h = Harness(PROFILE)
    h.send(data, chunk=chunk)
    h.wait(0.5)
    _recovers(h)


@FUZZ
@given(
    st.lists(st.one_of(lines.map(lambda s: s.encode("latin-1") + b"\r"), st.binary(max_size=8)), max_size=9)
)
def test_chunking_does_not_change_output(parts: list[bytes]) -> None:
    data = b"".join(parts)
    whole = Harness(PROFILE).send(data)
    assert Harness(PROFILE).send(data, chunk=1) == whole
    assert Harness(PROFILE).send(data, chunk=7) == whole
