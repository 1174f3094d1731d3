"""Hypothesis: the firmware modules' commands with hostile items, interleaved with base commands,
polls, control inputs (IN0 pulses, a sequencer program, the CRISP optics, the PMT, the focus signal)
and the passing of time, on every build that carries them (§9, §11, MS-39, MS-40). The builds,
letters and scripts are in tests/support/module_fuzz.py.

- Nothing raises; every line the controller sends is a form the specification allows.
- HALT then stops whatever a module runs (scans, arrays, MULTIAXIS patterns, limit seeks, ring-buffer
  playback, autofocus runs, CRISP routines, sequences, MS-76), after the lines that stop what HALT
  leaves running (a CRISP lock `LK F=79`, tracking `UL`, `ARM Z`, autofocus IN0 mode 103 and `AM`):
  once the clock settles nothing is busy and `W X` reads the `axes` observable.
- A line answering `:N-…` at once changes nothing observable: the control channel's snapshot, the
  card's and axes' settings and every module's own settings and state machine. One exception: an
  autofocus run that finds no contrast logs 300 (MS-AF-3), at once when its range is 0. HALT, whose
  `:N-21` says that it did stop a move (MS-76), is no line of the batches, and a search that fails
  (`SI`, `:N-5` after moving, MS-SI-1) answers late, not at once.
- Missing, extra and out-of-range items answer the documented code: a command that needs items alone
  `:N-3`, a letter it does not document `:N-2`, a value beyond the 32-bit variable `:N-4` (MS-26,
  MS-40), each changing nothing.
"""

from __future__ import annotations

import re
from dataclasses import fields, is_dataclass
from enum import Enum
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from emulator.device import MAIN
from protocols import ms2000 as p
from tests.support.fuzz import fuzz_settings, ms2000_items
from tests.support.module_fuzz import (
    BUILDS,
    EXTENDED,
    WORDS,
    Control,
    Step,
    key_of,
    modules_of,
    steps,
    stop_lines,
)
from tests.unit.ms2000.conftest import Harness

ERROR_CODES = {str(int(code)) for code in p.ErrorCode}
#: every line a controller may send on its main port here: an error with a documented code (MS-39);
#: `:A` with or without values (MS-35); value first, `X=1 :A` (SECURE, LED, WRDAC); colon first,
#: `:X=1 A`; `N`/`B` (status, `VB X` bit 0); `H`/`L`, `p`/`P` (`VB X` IN1 and button lines); an IN0
#: mode-5 report, milliseconds then positions (MS-90, TRACKING's ends with the sum); and the bare
#: lines of §11: CRISP's focus-curve samples `<z units> <error>` and the `end` after them, its
#: `EXTRA X?` LCD line (state, sum and error 5 wide, one space); TRACKING's `LR Z` report and
#: AUTOFOCUS's `AFINFO`, line by line
REPLY_LINE = re.compile(
    rb":N-(?P<code>\d+)"
    rb"|:A(?: [ -~]*)?"
    rb"|(?:[A-Z_]+=\S+ )+:A"
    rb"|:(?:[A-Z_]+=\S+ )+A ?"
    rb"|[NBHLpP]"
    rb"|\d+(?: -?\d+(?:\.\d+)?)* ?"
    rb"|-?\d+(?:\.\d+)? -?\d+|end"
    rb"|[A-Za-z1-5][ \d]{4}\d[ \d-]{4}\d "
    rb"|PhotoTrack state: [ICTPE]|Sum: \d+ min \d+|Error X: -?\d+\.\d{3} Y: -?\d+\.\d{3}"
    rb"|Quad order: [0-3]|Cal value: \d+\.\d{6}|(?:XY|Z|Cal) range: \d+\.\d{6} mm|Focus: (?:on|off)"
    rb"|Speed: \d+ %|Range: \d+\.\d{6} mm|Mode: (?:Normal|Hill)|Hill offset: \d+ %"
    rb"|Min contrast: \d+|Frame offset: \d+\.\d{6}|Last max focus: \d+"
    rb"|(?:Start|Final) pos: -?\d+(?:\.\d+)?"
)
WHERE_VALUE = re.compile(r"-?\d+(?:\.\d+)?")
#: more than the lines of any batch
MAX_HALTS = 64


# ---- what is checked --------------------------------------------------------------------------------


def reply_lines(data: bytes) -> list[bytes]:
    """The complete lines of `data` (CR LF, or CR only after `VB X=8`)."""
    parts = re.split(rb"\r\n|\r", data)
    assert parts[-1] == b"", data  # nothing half sent
    return [part.lstrip(b"\n") for part in parts[:-1]]


def check_replies(data: bytes) -> None:
    for line in reply_lines(data):
        match = REPLY_LINE.fullmatch(line)
        assert match, data
        assert match["code"] is None or match["code"].decode() in ERROR_CODES, data


def check_frame(h: Harness, data: bytes) -> None:
    """A TTL REPORT frame on the auxiliary port: per motor axis its id byte and a 32-bit count, then
    CR (MS-TTLREP-2)."""
    ids = bytes(axis.s.ll_id for axis in h.dev.axes)
    assert len(data) == 5 * len(ids) + 1 and data[-1:] == b"\r", data
    assert data[:-1:5] == ids, data


def main_output(h: Harness) -> bytes:
    """What the controller has sent on its main port; frames on another port are checked on the way."""
    main = b""
    for emission in h.take_emissions():
        if emission.channel == MAIN:
            main += emission.data
        else:
            check_frame(h, emission.data)
    return main


def command(h: Harness, line: str) -> bytes:
    """`Harness.cmd` with the auxiliary port kept apart: the main port's reply."""
    h.wait(0)
    h.write(line.encode("latin-1") + b"\r")
    return main_output(h)


def run_step(h: Harness, step: Step) -> bytes:
    """Carry out one step; what the main port sent meanwhile."""
    if isinstance(step, Control):
        h.control(step.name, **step.params)
        return main_output(h)
    if isinstance(step, float):
        h.wait(step)
        return main_output(h)
    return command(h, step)


def error_answer(data: bytes) -> bool:
    """`data` is one error line and nothing else."""
    lines = reply_lines(data)
    return len(lines) == 1 and lines[0].startswith(b":N-")


def recovers(h: Harness, build: str) -> None:
    """Stop what HALT leaves running (a CRISP lock, tracking, a sequence, repeated autofocus), HALT,
    let the clock settle until nothing is busy, then `W X` is the observable's position. Lines queued
    behind a command that replies late (`SI`, `AF`) run once HALT cancels it (MS-13, MS-76) and may
    start something again: HALT then comes again, at most once per line of the batch."""
    for line in stop_lines(build):
        check_replies(command(h, line))
    for _ in range(MAX_HALTS):
        check_replies(command(h, "\\"))
        h.wait(0.5)
        if not h.dev.busy(h.t):
            break
    h.idle(limit=30.0)
    h.wait(0.5)
    check_replies(main_output(h))
    reply = command(h, "W X")
    terminator = b"\r" if h.dev.card.vb_flags & 8 else b"\r\n"
    position = h.snapshot()["axes"]["X"]["position"]
    assert WHERE_VALUE.fullmatch(position), position
    assert reply == f":A {position}".encode() + terminator, reply


def observed(h: Harness) -> dict[str, Any]:
    """What a line may change: the control snapshot, card and axis settings, axis origins, and each
    module's own attributes as plain data (a timer by its due time, an axis by its type)."""
    dev = h.dev
    return {
        "snapshot": h.snapshot(),
        "card": plain(dev.card),
        "axes": [(plain(a.s), plain(a.auto), a.origin) for a in dev.axes],
        "modules": [plain(vars(m)) for m in dev.modules._modules],
    }


def plain(value: Any) -> Any:
    """`value` as comparable data: containers and dataclasses opened, other objects by type."""
    if value is None or isinstance(value, str | int | float):
        return value
    if isinstance(value, Enum):
        return value.name
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    if isinstance(value, set | frozenset):
        return sorted(repr(v) for v in value)
    if is_dataclass(value) and not isinstance(value, type):
        return {f.name: plain(getattr(value, f.name)) for f in fields(value)}
    return type(value).__name__  # the host, an axis, a callable: who, not what state


# ---- properties -------------------------------------------------------------------------------------

#: per build and property in `make test` (derandomized, about 15 s in all); `make soak` runs 10 000
FUZZ = fuzz_settings(40)


@pytest.mark.parametrize("build", BUILDS)
@FUZZ
@given(data=st.data())
def test_module_lines_answer_allowed_forms_and_recover(build: str, data: st.DataObject) -> None:
    h = Harness(BUILDS[build])
    for step in data.draw(steps(build)):
        check_replies(run_step(h, step))
    recovers(h, build)


#: an autofocus run that finds no contrast logs it (MS-AF-3)
NO_CONTRAST = 300


def failed_autofocus(step: str, out: bytes) -> bool:
    """A bare `AF`/`AFC` answering `:N-5` at once: refused, or a run that found no contrast and
    logged 300 (at once when `AF Y=0` leaves it no range to scan)."""
    spec = p.lookup(step.strip())
    return spec is not None and spec.key in ("AF", "AFC") and reply_lines(out) == [b":N-5"]


@pytest.mark.parametrize("build", BUILDS)
@FUZZ
@given(data=st.data())
def test_module_line_answering_an_error_changes_nothing(build: str, data: st.DataObject) -> None:
    h = Harness(BUILDS[build])
    for step in data.draw(steps(build)):
        if not isinstance(step, str):
            run_step(h, step)
            continue
        before = observed(h)
        out = command(h, step)
        if error_answer(out):
            after = observed(h)
            if failed_autofocus(step, out):
                # refused (a run going, speed 0) it logs nothing; run without contrast, 300
                logged, kept = after["snapshot"].pop("error_log"), before["snapshot"].pop("error_log")
                assert logged in (kept, [*kept, NO_CONTRAST]), (step, out)
            assert after == before, (step, out)
    recovers(h, build)


#: commands that answer `:N-3` alone: settings commands without a bare form (MS-30; `AL`, §11);
#: `SN` in a build without SCAN MODULE has no scan to start (MS-SCAN-1)
NEED_ITEMS = {"CCB", "WRDAC", "PD", "LED", "ZS", "LD", "SI", "NR", "NV", "SECURE", "AL", "LR", "AFADJ", "AM"}
#: beyond ±(2³¹−1) (MS-26)
HUGE = ("99999999999", "-99999999999", "2147483648")
UPPER = "ABCDEFGHIJKLMNOPQRSTUVWXYZ"
#: the encoder kind each `SI` module serves (MS-SI-3)
SI_KINDS = {"SEARCH INDEX": "linear", "SEEK LIMITS": "rotary"}


def needs_items(key: str, modules: tuple[str, ...]) -> bool:
    return key in NEED_ITEMS or (key == "SN" and "SCAN MODULE" not in modules)


def refused_whole(build: str, key: str) -> bool:
    """In a `PZ` build the converter drives the piezo: `WRDAC` is `:N-5` whatever its items
    (MS-DAC-3)."""
    return key == "WRDAC" and "PZ" in Harness(BUILDS[build]).dev.cfg.build_name


def module_words(build: str) -> dict[str, str]:
    """The words of module commands that take items (what an extended base command answers is its
    own; `AFINFO` is a report and reads none); `SI` with the letters of axes whose encoder kind the
    build serves (others are `:N-1`, MS-SI-3)."""
    dev = Harness(BUILDS[build]).dev
    kinds = {kind for module, kind in SI_KINDS.items() if module in dev.cfg.modules}
    si_axes = "".join(a.letter for a in dev.axes if a.cfg.encoder in kinds)
    words = {w: letters for w, letters in WORDS[build].items() if key_of(w) not in EXTENDED and letters}
    return {w: si_axes if key_of(w) == "SI" else letters for w, letters in words.items()}


MODULE_WORDS = {build: module_words(build) for build in BUILDS}
#: TTL REPORT has no command of its own (`TTL X=6` is the base command's)
COMMAND_BUILDS = [build for build in BUILDS if MODULE_WORDS[build]]


@st.composite
def bad_line(draw: st.DrawFn, build: str) -> tuple[str, str]:
    """A module command line with one documented fault, and the code it answers."""
    words = MODULE_WORDS[build]
    word = draw(st.sampled_from(sorted(words)))
    letters = words[word]
    faults = ["extra", "huge"] + (["missing"] if needs_items(key_of(word), modules_of(build)) else [])
    fault = draw(st.sampled_from(faults))
    if fault == "missing":
        return word, "5" if refused_whole(build, key_of(word)) else "3"
    if fault == "huge":
        letter = draw(st.sampled_from(letters))
        bad = f"{letter}={draw(st.sampled_from(HUGE))}"
        # other letters only: a repeated letter's last item wins (MS-27), whatever came before it
        rest = [c for c in letters if c != letter]
        values = st.sampled_from(["0", "1", "1e9"])
        others = (
            st.lists(st.builds("{}={}".format, st.sampled_from(rest), values), max_size=3)
            if rest
            else st.just([])
        )
        code = "4"
    else:
        # not one of every letter the command takes (SI: all motor axes, served or not)
        undocumented = st.sampled_from([c for c in UPPER if c not in WORDS[build][word]])
        bad = draw(st.builds("{}{}".format, undocumented, st.sampled_from(["=0", "=1", "?", "+"])))
        others = st.lists(ms2000_items(letters).filter(lambda item: item[:1].upper() in letters), max_size=3)
        code = "2"
    items = draw(others)
    items.insert(draw(st.integers(0, len(items))), bad)
    return " ".join([word, *items]), "5" if refused_whole(build, key_of(word)) else code


@pytest.mark.parametrize("build", COMMAND_BUILDS)
@FUZZ
@given(data=st.data())
def test_bad_items_answer_the_documented_code(build: str, data: st.DataObject) -> None:
    line, code = data.draw(bad_line(build))
    h = Harness(BUILDS[build])
    before = observed(h)
    assert command(h, line) == f":N-{code}\r\n".encode(), line
    assert observed(h) == before, line


# ---- what the properties found ------------------------------------------------------------------


def test_ring_buffer_pointer_set_beside_a_clear_stays_in_the_buffer() -> None:
    """`RM X=0 Z=1` cleared the buffer, then set the pointer past its end: the next trigger raised
    IndexError (MS-RB-4)."""
    h = Harness(BUILDS["default"])
    for line in ("LD X=1", "LD X=2"):
        assert h.cmd(line) == b":A\r\n"
    assert h.cmd("RM X=0 Z=1") == b":A\r\n"
    assert h.cmd("RM Z?") == b":A Z=0\r\n"
    assert h.cmd("LD X=5") == b":A\r\n"
    assert h.cmd("RM") == b":A\r\n"
    h.idle()
    assert h.cmd("W X") == b":A 5\r\n"


def test_multiaxis_restart_that_fails_sets_no_letter() -> None:
    """`MM X=2 R=82` without a speed answers `:N-5` (MS-MULTI-2) and used to keep X=2."""
    h = Harness(BUILDS["all-modules"])
    before = observed(h)
    assert h.cmd("MM X=2 R=82") == b":N-5\r\n"
    assert observed(h) == before
    assert h.cmd("MM X? Y?") == b":A X=0.000000 Y=0.000000\r\n"
