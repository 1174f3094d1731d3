"""Hypothesis: the firmware modules' commands with hostile items, interleaved with base commands,
polls and the passing of time, on every build that carries them (§9, MS-39, MS-40).

- Nothing raises; every line the controller sends is a form the specification allows.
- HALT then stops whatever a module runs (scans, arrays, MULTIAXIS patterns, limit seeks, ring-buffer
  playback, MS-76): once the clock settles nothing is busy and `W X` reads the `axes` observable.
- A line answering `:N-…` at once changes nothing observable: the control channel's snapshot, the
  card's and axes' settings and every module's own settings and state machine. No exception was
  needed: HALT, whose `:N-21` says that it did stop a move (MS-76), is no line of the batches, and
  a search that fails (`SI`, `:N-5` after moving, MS-SI-1) answers late, not at once.
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

from emulator.profile import Profile, load_profile
from protocols import ms2000 as p
from tests.support.fuzz import fuzz_settings, ms2000_items, ms2000_lines
from tests.support.ms2000_builds import SEQ_LIKE
from tests.unit.ms2000.conftest import Harness

#: the bundled builds between them carry every module; SEQ_LIKE adds PLANAR CORRECTION and DAC OUT
BUILDS: dict[str, Profile[Any]] = {
    "default": load_profile("ms2000"),
    "all-modules": load_profile("ms2000-all-modules"),
    "scan": load_profile("ms2000-scan"),
    "tracer": load_profile("ms2000-tracer"),
    "uservo": load_profile("ms2000-uservo"),
    "seq-like": load_profile("ms2000", SEQ_LIKE),
}
#: the letters each module command documents (§9); None: the build's motor axes
LETTERS: dict[str, str | None] = {
    "AR": "XYZFT",
    "AH": "XY",
    "AIJ": "XY",
    "SN": "XYZF",
    "NR": "XYZF",
    "NV": "XYZF",
    "MM": "XYZFR",
    "CCB": "Z",
    "WRDAC": "X",
    "PD": "XYZ",
    "LED": "XYZF",
    "RM": "XYZF",
    "LD": None,
    "ZS": "XYZF",
    "SI": None,
    "SECURE": "XYZFT",
}
#: base commands that modules extend: `JS F/T` (XY KNOBS), `VB T` (NO CHANGE SETTINGS), `@`
EXTENDED: dict[str, str | None] = {"JS": "XYZFT", "VB": "XYZT", "@": None}
#: base commands and polls between the module lines: moves, TTL modes the modules serve, reports
BASE_LINES = (
    "/",
    "W X Y Z",
    "RS X",
    "M X=5000 Y=-5000",
    "R X=-20000",
    "H X Y",
    "Z",
    "TTL X=1",
    "TTL X=2",
    "TTL X=4",
    "TTL X=5",
    "TTL X=7",
    "TTL Y=2",
    "TTL Y=8",
    "TTL Y=9",
    "RT Y=5 Z=20",
    "VB X=1",
    "VB X=8",
    "VB X=0",
    "VB Z=2",
)
#: well-formed module lines that set a module running (or stop it), so that the hostile lines also
#: meet scans, arrays, patterns, searches and playback under way; each where its build has the words
RUN_SCRIPTS: tuple[tuple[str, ...], ...] = (
    ("AR X=3 Y=2 Z=0.5 F=-0.5", "AR"),
    ("AR X=2 Y=3", "TTL X=7", "RM X=1", "RM"),
    ("AIJ X=2 Y=2",),
    ("LD X=1000 Y=2000", "LD X+ Y+", "RM F=2", "RM"),
    ("SN X=1 Y=2 F=1", "NR X=0 Y=0.2 Z=24", "NV X=0 Y=0.05 Z=3 F=1", "SN"),
    ("MM X=0.5 Y=2 Z=0.1 F=4", "MM"),
    ("MM X=0.3 Y=1 Z=0.05 F=197", "MM"),
    ("MM R=80",),
    ("SI X=0",),
    ("SI Z=1",),
    ("CCB Z=1",),
    ("ZS X=10 Y=3", "TTL X=4", "RM"),
    ("SECURE X=1",),
    ("WRDAC X=5",),
    ("LED X=50",),
    ("PD X=0.01 Y=2",),
)
#: device seconds to let pass: modules run scans, arrays and patterns meanwhile
WAITS = (0.01, 0.2, 1.0, 3.0)
ERROR_CODES = {str(int(code)) for code in p.ErrorCode}
#: every line a controller may send here: an error with a documented code (MS-39); `:A` with or
#: without values (MS-35); value first, `X=1 :A` (SECURE, LED, WRDAC); colon first, `:X=1 A`;
#: `N`/`B` (status, `VB X` bit 0); `H`/`L`, `p`/`P` (`VB X` IN1 and button lines); an IN0 mode-5
#: report, milliseconds then positions (MS-90)
REPLY_LINE = re.compile(
    rb":N-(?P<code>\d+)"
    rb"|:A(?: [ -~]*)?"
    rb"|(?:[A-Z_]+=\S+ )+:A"
    rb"|:(?:[A-Z_]+=\S+ )+A ?"
    rb"|[NBHLpP]"
    rb"|\d+(?: -?\d+(?:\.\d+)?)* ?"
)
WHERE_VALUE = re.compile(r"-?\d+(?:\.\d+)?")
#: more than the lines of any batch
MAX_HALTS = 64


def key_of(word: str) -> str:
    spec = p.lookup(word)
    assert spec is not None, word
    return spec.key


def words_of(build: str) -> dict[str, str]:
    """Every word (long name, shortcut, alias) of the module commands the build answers, and of the
    base commands modules extend, with the letters each documents."""
    dev = Harness(BUILDS[build]).dev
    modules = set(dev.cfg.modules)
    axes = "".join(a.letter for a in dev.axes)
    words: dict[str, str] = {}
    for spec in p.COMMANDS:
        if spec.is_base and spec.key not in EXTENDED:
            continue
        if not spec.is_base and not modules.intersection(spec.modules):
            continue
        letters = EXTENDED[spec.key] if spec.is_base else LETTERS[spec.key]
        if spec.key == "SECURE" and "U_SERVO_LK" in modules:
            letters = "X"  # the servo insert has its position only (MS-SECURE-1)
        for word in spec.words():
            words[word] = axes if letters is None else letters
    return words


WORDS = {build: words_of(build) for build in BUILDS}


def steps(build: str) -> st.SearchStrategy[list[str | float]]:
    """A batch: hostile module lines, scripts that start something, waits (floats; each twice as
    likely) and base lines and polls."""
    module = ms2000_lines(WORDS[build]).map(lambda line: [line])
    known = {*WORDS[build], *(line.split()[0] for line in BASE_LINES)}
    scripts = [list(s) for s in RUN_SCRIPTS if all(line.split()[0] in known for line in s)]
    runs = st.sampled_from(scripts)
    base = st.sampled_from(BASE_LINES).map(lambda line: [line])
    wait = st.sampled_from(WAITS).map(lambda seconds: [seconds])
    step: st.SearchStrategy[list[str | float]] = st.one_of(module, module, runs, runs, base, wait, wait)
    return st.lists(step, max_size=12).map(lambda parts: [s for part in parts for s in part])


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


def error_answer(data: bytes) -> bool:
    """`data` is one error line and nothing else."""
    lines = reply_lines(data)
    return len(lines) == 1 and lines[0].startswith(b":N-")


def recovers(h: Harness) -> None:
    """HALT, let the clock settle until nothing is busy, then `W X` is the observable's position.
    Lines queued behind a command that replies late (`SI`) run once HALT cancels it (MS-13, MS-76)
    and may start something again: HALT then comes again, at most once per line of the batch."""
    for _ in range(MAX_HALTS):
        check_replies(h.cmd("\\"))
        h.wait(0.5)
        if not h.dev.busy(h.t):
            break
    h.idle(limit=30.0)
    h.wait(0.5)
    check_replies(h.output())
    reply = h.cmd("W X")
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

FUZZ = fuzz_settings(80)


@pytest.mark.parametrize("build", BUILDS)
@FUZZ
@given(data=st.data())
def test_module_lines_answer_allowed_forms_and_recover(build: str, data: st.DataObject) -> None:
    h = Harness(BUILDS[build])
    for step in data.draw(steps(build)):
        if isinstance(step, float):
            h.wait(step)
            check_replies(h.output())
        else:
            check_replies(h.cmd(step))
    recovers(h)


@pytest.mark.parametrize("build", BUILDS)
@FUZZ
@given(data=st.data())
def test_module_line_answering_an_error_changes_nothing(build: str, data: st.DataObject) -> None:
    h = Harness(BUILDS[build])
    for step in data.draw(steps(build)):
        if isinstance(step, float):
            h.wait(step)
            continue
        before = observed(h)
        out = h.cmd(step)
        if error_answer(out):
            assert observed(h) == before, (step, out)
    recovers(h)


#: commands that answer `:N-3` alone: settings commands without a bare form (MS-30); `SN` in a
#: build without SCAN MODULE has no scan to start (MS-SCAN-1)
NEED_ITEMS = {"CCB", "WRDAC", "PD", "LED", "ZS", "LD", "SI", "NR", "NV", "SECURE"}
#: beyond ±(2³¹−1) (MS-26)
HUGE = ("99999999999", "-99999999999", "2147483648")
UPPER = "ABCDEFGHIJKLMNOPQRSTUVWXYZ"
#: the encoder kind each `SI` module serves (MS-SI-3)
SI_KINDS = {"SEARCH INDEX": "linear", "SEEK LIMITS": "rotary"}


def needs_items(key: str, modules: tuple[str, ...]) -> bool:
    return key in NEED_ITEMS or (key == "SN" and "SCAN MODULE" not in modules)


def module_words(build: str) -> dict[str, str]:
    """The words of module commands only (what an extended base command answers is its own); `SI`
    with the letters of axes whose encoder kind the build serves (others are `:N-1`, MS-SI-3)."""
    dev = Harness(BUILDS[build]).dev
    kinds = {kind for module, kind in SI_KINDS.items() if module in dev.cfg.modules}
    si_axes = "".join(a.letter for a in dev.axes if a.cfg.encoder in kinds)
    words = {w: letters for w, letters in WORDS[build].items() if key_of(w) not in EXTENDED}
    return {w: si_axes if key_of(w) == "SI" else letters for w, letters in words.items()}


MODULE_WORDS = {build: module_words(build) for build in BUILDS}


@st.composite
def bad_line(draw: st.DrawFn, build: str) -> tuple[str, str]:
    """A module command line with one documented fault, and the code it answers."""
    words = MODULE_WORDS[build]
    word = draw(st.sampled_from(sorted(words)))
    letters = words[word]
    faults = ["extra", "huge"] + (
        ["missing"] if needs_items(key_of(word), BUILDS[build].config.modules) else []
    )
    fault = draw(st.sampled_from(faults))
    if fault == "missing":
        return word, "3"
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
    return " ".join([word, *items]), code


@pytest.mark.parametrize("build", BUILDS)
@FUZZ
@given(data=st.data())
def test_bad_items_answer_the_documented_code(build: str, data: st.DataObject) -> None:
    line, code = data.draw(bad_line(build))
    h = Harness(BUILDS[build])
    before = observed(h)
    assert h.cmd(line) == f":N-{code}\r\n".encode(), line
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
