"""What the MS2000 module fuzz properties (tests/unit/ms2000/test_fuzz_modules.py) draw from: the
builds, the letters each module command documents (§11), base lines, scripts that set modules
running, the lines that stop them again, and the batches of steps made of all these.

A step is a command line (str), device seconds to let pass (float) or a control input (`Control`:
an IN0 pulse, a program, a signal the module reads).
"""

from __future__ import annotations

from typing import Any, NamedTuple

from hypothesis import strategies as st

from emulator.profiles.profile import Profile, load_profile
from protocols import ms2000 as p
from tests.support.fuzz import ms2000_lines
from tests.unit.ms2000.conftest import Harness


class Control(NamedTuple):
    """A control-channel input (`Harness.control`) as a step of a batch."""

    name: str
    params: dict[str, Any]


Step = str | float | Control

#: the bundled builds between them carry every module
BUILDS: dict[str, Profile[Any]] = {
    "default": load_profile("ms2000"),
    "all-modules": load_profile("ms2000-all-modules"),
    "scan": load_profile("ms2000-scan"),
    "tracer": load_profile("ms2000-tracer"),
    "uservo": load_profile("ms2000-uservo"),
    "seq": load_profile("ms2000-seq"),
    "crisp": load_profile("ms2000-crisp"),
    "pz-crisp": load_profile("ms2000-pz-crisp"),
    "af": load_profile("ms2000-af"),
    "ttlrep": load_profile("ms2000-ttlrep"),
    "track": load_profile("ms2000-track"),
    "dled": load_profile("ms2000-dled"),
}
#: the letters each module command documents (§11); None: the build's motor axes; "": none at all
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
    "RM": "XYZF",
    "LD": None,
    "ZS": "XYZF",
    "SI": None,
    "SECURE": "XYZFT",
    "ARM": "XYZ",
    "UL": "XYZF",
    "AL": "XYZ",
    "AF": "XYZF",
    "AFC": "XYF",
    "AFADJ": "XYZ",
    "AM": "XY",
    "AFINFO": "",
}
#: commands whose letters depend on the module serving them in the build
LETTERS_BY_MODULE: dict[str, dict[str, str]] = {
    "LED": {"LED DIMMER": "XYZF", "DLED": "XYTR"},
    "LK": {"CRISP": "XYZFTM", "TRACKING": "XYZFT"},
    "LR": {"CRISP": "XYZFT", "TRACKING": "XYZF"},
}
#: base commands that modules extend: `JS F/T` (XY KNOBS), `VB T` (NO CHANGE SETTINGS), `@`,
#: `EXTRA X? Y? Z` (CRISP)
EXTENDED: dict[str, str | None] = {"JS": "XYZFT", "VB": "XYZT", "@": None, "EX": "XYZM"}
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
PULSE = Control("ttl_in0", {"pulse_ms": 1})
#: a sequence that steps Z, toggles TTL0 and an analog output and chains its blocks
SEQUENCE = Control(
    "sequencer",
    {
        "blocks": [
            {"start": [2], "repeat": [1], "delay_ms": 50, "repetitions": 2, "action": 1},
            {"start": [6, 1], "delay_ms": 20, "action": 4},
            {"start": [4], "repeat": [12], "delay_ms": 30, "repetitions": 3},
        ],
        "outputs": [
            {"kind": "ttl", "index": 0, "start": [5, 1], "stop": [1]},
            {"kind": "avo", "index": 0, "step": [7, 3], "reset": [6, 2], "step_size": 0.5, "initial": 1},
            {"kind": "stg", "axis": "Z", "step": [5, 3], "reset": [2], "step_size": 100, "initial": 0},
        ],
    },
)
#: the same for the modules that need a control input or a TTL mode, where the build has the module
MODULE_SCRIPTS: dict[str, tuple[tuple[Step, ...], ...]] = {
    "CRISP": (
        ("LK", "LK", "LK"),  # LED on, ready, lock
        ("LK F=72",),  # log-amp calibration
        ("LK F=67",),  # gain calibration
        ("LK F=97",),  # focus curve: a stream of `<z> <error>` lines, then `end`
        ("LK F=111",),  # offset reset
        (Control("crisp", {"surface_um": 3, "drift_um_per_s": 2}), "LK F=83"),
        ("LK F=82", "TTL X=9", PULSE),
        ("TTL Y=11", "LK F=83", "M Z=50"),
        ("TTL Y=12",),
    ),
    "AUTOFOCUS": (
        (Control("focus", {"peak_um": 10}), "AF"),
        ("AF Z=1 Y=0.05", "AF"),
        ("AFC",),
        ("AM X=1", "M X=100"),
        ("TTL X=3", PULSE),
        ("RT X=200", "TTL X=103"),
    ),
    "SEQUENCER": (
        (SEQUENCE, "ARM X", "ARM"),
        (SEQUENCE, "ARM", PULSE, "ARM"),
        ("ARM Y=0", "ARM"),
    ),
    "TTL REPORT": (
        ("TTL X=6", PULSE),
        ("TTL X=6", PULSE, PULSE),  # the second edge overruns the first frame
    ),
    "TRACKING": (
        (Control("pmt", {"x_um": 8, "y_um": -4, "vy_um_s": 20, "sigma_um": 5, "brightness": 1000}), "LK"),
        (Control("pmt", {"q1": 200, "q2": 100, "q3": 100, "q4": 200}), "LK"),
        (Control("pmt", {"x_um": 3, "y_um": 0, "sigma_um": 5, "brightness": 1000}), "LK X"),
        ("UL X=1", "LK"),
        ("LK Y",),
    ),
    "DLED": (
        ("LED X=50 Y=30", "TTL X=20", PULSE),
        ("LED X=50 Y=30", "RT Y=20", "TTL X=21", PULSE, PULSE),
        ("LED X=40", "TTL X=22", Control("ttl_in0", {"pulse_ms": 30})),
        ("LED Y=60", "TTL X=23", PULSE),
        ("LED R=10 T=5",),
    ),
}
#: what stops a module's runs that HALT leaves going: an engaged CRISP lock, tracking, a sequence
#: with ALWAYS blocks, IN0 mode 103 and `AM X=1` autofocus
STOP_LINES: dict[str, tuple[str, ...]] = {
    "CRISP": ("LK F=79",),
    "TRACKING": ("UL",),
    "SEQUENCER": ("ARM Z",),
    "AUTOFOCUS": ("TTL X=0", "AM X=0"),
}
#: device seconds to let pass: modules run scans, arrays and patterns meanwhile
WAITS = (0.01, 0.2, 1.0, 3.0)


def key_of(word: str) -> str:
    spec = p.lookup(word)
    assert spec is not None, word
    return spec.key


def modules_of(build: str) -> tuple[str, ...]:
    return tuple(BUILDS[build].config.modules)


def letters_of(key: str, modules: tuple[str, ...]) -> str | None:
    """The letters command `key` documents in a build with `modules`: the serving module's (CRISP
    outranks TRACKING; of LED DIMMER and DLED the later one serves, §11)."""
    by_module = LETTERS_BY_MODULE.get(key, {})
    serving = [m for m in modules if m in by_module]
    if "CRISP" in serving:
        return by_module["CRISP"]
    if serving:
        return by_module[serving[-1]]
    return LETTERS[key]


def words_of(build: str) -> dict[str, str]:
    """Every word (long name, shortcut, alias) of the module commands the build answers, and of the
    base commands modules extend, with the letters each documents."""
    dev = Harness(BUILDS[build]).dev
    modules = tuple(dev.cfg.modules)
    axes = "".join(a.letter for a in dev.axes)
    words: dict[str, str] = {}
    for spec in p.COMMANDS:
        if spec.is_base and spec.key not in EXTENDED:
            continue
        if not spec.is_base and not set(modules).intersection(spec.modules):
            continue
        letters = EXTENDED[spec.key] if spec.is_base else letters_of(spec.key, modules)
        if spec.key == "SECURE" and "U_SERVO_LK" in modules:
            letters = "X"  # the servo insert has its position only (MS-SECURE-1)
        for word in spec.words():
            words[word] = axes if letters is None else letters
    return words


WORDS = {build: words_of(build) for build in BUILDS}


def scripts_of(build: str) -> list[list[Step]]:
    """The run scripts whose words the build answers, and those of its modules."""
    known = {*WORDS[build], *(line.split()[0] for line in BASE_LINES)}
    scripts: list[list[Step]] = [list(s) for s in RUN_SCRIPTS if all(line.split()[0] in known for line in s)]
    for module in modules_of(build):
        scripts += [list(s) for s in MODULE_SCRIPTS.get(module, ())]
    return scripts


def stop_lines(build: str) -> list[str]:
    return [line for module in modules_of(build) for line in STOP_LINES.get(module, ())]


def steps(build: str) -> st.SearchStrategy[list[Step]]:
    """A batch: hostile module lines, scripts that start something, waits (each twice as likely) and
    base lines and polls."""
    module = ms2000_lines(WORDS[build]).map(lambda line: [line])
    runs = st.sampled_from(scripts_of(build))
    base = st.sampled_from(BASE_LINES).map(lambda line: [line])
    wait = st.sampled_from(WAITS).map(lambda seconds: [seconds])
    step: st.SearchStrategy[list[Step]] = st.one_of(module, module, runs, runs, base, wait, wait)
    return st.lists(step, max_size=12).map(lambda parts: [s for part in parts for s in part])
