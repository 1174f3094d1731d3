"""Hostile profiles (issue #9): each is refused with one line, exit code 1, quickly and in little
memory, through `load_profile` and through `stage-emu validate`; the file reader's own messages."""

from __future__ import annotations

import os
import time
import tracemalloc
from pathlib import Path

import pytest
from click.testing import CliRunner

from emulator.cli import main
from emulator.profiles.profile import ProfileError, load_profile
from emulator.profiles.yamlsource import (
    MAX_DEPTH,
    MAX_FILE_BYTES,
    SourceError,
    load_located,
    merge,
    read_source,
)
from scripts.soak.hostile_profiles import BIG, SECRET, write_cases

#: a sanity bound only, on this process's CPU time (a loaded machine cannot inflate it): the cases
#: stop at a limit long before (well under a second each)
SLOW_S = 5.0
MEMORY_BYTES = 100 * 1024 * 1024


@pytest.fixture(scope="module")
def cases(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, str]]:
    return {
        name: (path, expected) for name, path, expected in write_cases(tmp_path_factory.mktemp("hostile"))
    }


NAMES = [
    "alias_bomb",
    "big_list",
    "deep_nesting",
    "self_alias",
    "extends_chain",
    "non_utf8",
    "nul_byte",
    "extends_shadow",
    "extends_shadow_yaml",
    "extends_mapping",
    "extends_bad_yaml",
    "extends_directory",
    "extends_fifo",
    "extends_missing",
    "extends_rig",
    "nan",
    "inf",
    "huge",
    "other_family",
    "bad_version",
    "long_version",
    "two_line_description",
    "wide_extends",
]


def test_the_corpus_has_every_case(cases: dict[str, tuple[Path, str]]) -> None:
    assert sorted(cases) == sorted(NAMES)


def assert_refused(message: str, expected: str) -> None:
    assert expected in message
    assert "\n" not in message.strip() and "Traceback" not in message
    assert SECRET not in message


@pytest.mark.parametrize("name", NAMES)
def test_load_profile_refuses(cases: dict[str, tuple[Path, str]], name: str) -> None:
    path, expected = cases[name]
    start = time.process_time()
    with pytest.raises(ProfileError) as info:
        load_profile(str(path))
    assert time.process_time() - start < SLOW_S
    assert_refused(str(info.value), expected)


@pytest.mark.parametrize("name", NAMES)
def test_validate_refuses(cases: dict[str, tuple[Path, str]], name: str) -> None:
    path, expected = cases[name]
    start = time.process_time()
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert time.process_time() - start < SLOW_S
    assert result.exit_code == 1
    assert result.exception is None or isinstance(result.exception, SystemExit)
    assert_refused(result.stderr, expected)
    assert len(result.stderr.splitlines()) == 1


@pytest.mark.parametrize("name", BIG)
def test_big_cases_stay_small(cases: dict[str, tuple[Path, str]], name: str) -> None:
    """The alias bomb stops at the node limit, the 50 MB list at the size limit."""
    path, _ = cases[name]
    tracemalloc.start()
    try:
        with pytest.raises(ProfileError):
            load_profile(str(path))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < MEMORY_BYTES


def test_reader_names_each_kind_of_non_file(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "dir").mkdir()
    messages = {}
    for name in ("missing", "dir", "fifo"):
        with pytest.raises(SourceError) as info:
            read_source(tmp_path / name, name)
        messages[name] = str(info.value)
    assert messages == {
        "missing": "missing: does not exist",
        "dir": "dir: is a directory, not a file",
        "fifo": "fifo: is a FIFO (named pipe), not a regular file",
    }
    with pytest.raises(SourceError, match=r"^null: is a device, not a regular file$"):
        read_source("/dev/null", "null")


def test_reader_size_limit_is_exact(tmp_path: Path) -> None:
    path = tmp_path / "p.yaml"
    path.write_text("a: 1\n" + "#" * (MAX_FILE_BYTES - 6) + "\n")
    assert read_source(path).data == {"a": 1}
    path.write_text("a: 1\n" + "#" * (MAX_FILE_BYTES - 5) + "\n")
    with pytest.raises(SourceError, match="is larger than 1048576 bytes"):
        read_source(path)


def test_nesting_up_to_the_limit_loads() -> None:
    deepest = "[" * MAX_DEPTH + "]" * MAX_DEPTH
    assert load_located(deepest, "x").data is not None
    with pytest.raises(SourceError, match="x:1: nested deeper than 64 levels"):
        load_located("[" + deepest + "]", "x")


@pytest.mark.parametrize(
    ("text", "quoted", "unquoted"),
    [
        (
            "a: !secret 1\n",
            "x:1: not valid YAML: could not determine a constructor for the tag '!secret'",
            "x:1: not valid YAML",
        ),
        ("a: [1\n", "x:2: not valid YAML: did not find expected ',' or ']'", "x:2: not valid YAML"),
        ("a: 1\na: 2\n", "x:2: a: duplicate key", "x:2: duplicate key"),
        (
            "a: !!set {1: null}\n",
            "x:1: not valid YAML: tag tag:yaml.org,2002:set is not allowed",
            "x:1: not valid YAML: tag is not allowed",
        ),
        ("a: 2020-13-45\n", "x:1: not a valid value: month must be in 1..12", "x:1: not a valid value"),
        ("a: \x01\n", "x:1: not valid YAML: character U+0001 is not allowed", "x:1: not valid YAML"),
    ],
)
def test_yaml_errors_quote_only_when_asked(text: str, quoted: str, unquoted: str) -> None:
    """A file reached through `extends` is not quoted until it looks like a profile."""
    for quote, expected in ((True, quoted), (False, unquoted)):
        with pytest.raises(SourceError) as info:
            load_located(text, "x", quote)
        assert str(info.value) == expected


def test_yaml_1_2_floats_are_numbers() -> None:
    """`1e300` is a float (YAML 1.2), so a schema range can refuse it instead of 'not a number'."""
    assert load_located("a: 1e300\nb: -5E-3\nc: 1e\n", "x").data == {"a": 1e300, "b": -5e-3, "c": "1e"}


def test_huge_integer_is_one_line() -> None:
    with pytest.raises(SourceError, match=r"^x:1: not a valid value: Exceeds the limit \(4300 digits\)"):
        load_located("a: " + "9" * 5000 + "\n", "x")


def test_merge_keeps_positions_of_what_it_takes() -> None:
    base = load_located("a: {b: 1, c: 2}\nd: [1, 2]\n", "base")
    over = load_located("a: {c: 3}\nd: [4]\ne: 5\n", "over")
    merged = merge(base, over)
    assert merged.data == {"a": {"b": 1, "c": 3}, "d": [4], "e": 5}
    sources = {path: (where.source, where.line) for path, where in merged.places.items()}
    assert sources == {
        (): ("base", 1),
        ("a",): ("base", 1),
        ("a", "b"): ("base", 1),
        ("a", "c"): ("over", 1),
        ("d",): ("over", 2),
        ("d", 0): ("over", 2),
        ("e",): ("over", 3),
    }
