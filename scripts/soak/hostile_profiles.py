"""Hostile profile files: every case `stage-emu validate` and `load_profile` must refuse quickly,
with one line and little memory (issue #9). Big files are generated, never committed.

`write_cases(directory)` writes each case and returns (name, path, expected) tuples: `path` is the
profile to load and `expected` a substring of its one-line error. No message may contain `SECRET`,
which only the non-profile files hold.
"""

from __future__ import annotations

import os
from pathlib import Path

SECRET = "s3cr3t-hash"
#: cases that allocate most if loaded without limits (checked against a memory bound)
BIG = ("alias_bomb", "big_list")

_SHADOW = f"root:$6${SECRET}:19000:0:99999:7:::\ndaemon:*:19000:0:99999:7:::\n"


def _alias_bomb() -> str:
    """Billion laughs: nine levels of nine aliases, 9^9 strings once expanded."""
    lines = ['l0: &l0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    lines += [f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 9)}]" for i in range(1, 10)]
    return "spec: 1\ndevice: mp285\n" + "\n".join(lines) + "\n"


def _write_big_list(path: Path, megabytes: int = 50) -> None:
    """One flow list of `megabytes` MB, written in chunks."""
    chunk = "1," * (1 << 19)
    with path.open("w") as out:
        out.write("spec: 1\ndevice: mp285\nknobs: [")
        for _ in range(megabytes):
            out.write(chunk)
        out.write("1]\n")


def _profile(directory: Path, name: str, text: str) -> Path:
    path = directory / name
    path.write_text(text)
    return path


def _extends(directory: Path, name: str, ref: str) -> Path:
    return _profile(directory, name, f"spec: 1\ndevice: mp285\nextends: {ref}\n")


def write_cases(directory: Path) -> list[tuple[str, Path, str]]:
    """Write every hostile case into `directory` (created if needed)."""
    directory.mkdir(parents=True, exist_ok=True)
    cases: list[tuple[str, Path, str]] = []

    def add(name: str, path: Path, expected: str) -> None:
        cases.append((name, path, expected))

    add("alias_bomb", _profile(directory, "bomb.yaml", _alias_bomb()), "more than 100000 YAML nodes")
    big = directory / "big.yaml"
    _write_big_list(big)
    add("big_list", big, "is larger than 1048576 bytes")
    deep = _profile(directory, "deep.yaml", "spec: 1\ndevice: mp285\nknobs: " + "[" * 100_000 + "\n")
    add("deep_nesting", deep, "deep.yaml:3: nested deeper than 64 levels")
    add("self_alias", _profile(directory, "loop.yaml", "spec: 1\nknobs: &a [*a]\n"), "nested deeper than 64")

    chain = directory / "chain"
    chain.mkdir(exist_ok=True)
    for i in range(3000):
        _extends(chain, f"c{i}.yaml", f"c{i + 1}.yaml")
    _profile(chain, "c3000.yaml", "spec: 1\ndevice: mp285\n")
    add("extends_chain", chain / "c0.yaml", "extends: extends chain longer than 16 profiles")

    latin1 = directory / "latin1.yaml"
    latin1.write_bytes(b"spec: 1\ndevice: mp285\ndescription: caf\xe9\n")
    add("non_utf8", latin1, "latin1.yaml:3: not UTF-8 text, byte 38")
    add("nul_byte", _profile(directory, "nul.yaml", "spec: 1\ndevice: mp285\x00\n"), "not valid YAML")

    shadow = _profile(directory, "shadow", _SHADOW)
    add("extends_shadow", _extends(directory, "x-shadow.yaml", str(shadow)), "is not a profile file")
    _profile(directory, "shadow.yaml", _SHADOW)
    add("extends_shadow_yaml", _extends(directory, "x-shadow-yaml.yaml", "shadow.yaml"), "is not a profile")
    _profile(directory, "secrets.yaml", f"root: {SECRET}\n")
    add("extends_mapping", _extends(directory, "x-secrets.yaml", "secrets.yaml"), "is not a profile")
    _profile(directory, "tagged.yaml", f"!{SECRET} {SECRET}\n")
    add("extends_bad_yaml", _extends(directory, "x-tagged.yaml", "tagged.yaml"), "tagged.yaml:1: not valid")
    (directory / "dir.yaml").mkdir(exist_ok=True)
    add("extends_directory", _extends(directory, "x-dir.yaml", "dir.yaml"), "is a directory")
    fifo = directory / "pipe.yaml"
    if not fifo.exists():
        os.mkfifo(fifo)
    add("extends_fifo", _extends(directory, "x-fifo.yaml", "pipe.yaml"), "is a FIFO")
    add("extends_missing", _extends(directory, "x-missing.yaml", "missing.yaml"), "does not exist")
    add("extends_rig", _extends(directory, "x-rig.yaml", "rig.yaml"), "is a rig file, not a profile")
    _profile(directory, "rig.yaml", f"spec: 1\ndevices: [{{name: a, profile: {SECRET}}}]\n")

    for name, value, expected in (
        ("nan", ".nan", "settle_s: nan is not a finite number"),
        ("inf", "-.inf", "settle_s: -inf is not a finite number"),
        ("huge", "1e300", "settle_s: 1e+300 is out of range (>= 0, <= 3600)"),
    ):
        text = f"spec: 1\ndevice: mp285\nknobs:\n  settle_s: {value}\n"
        add(name, _profile(directory, f"{name}.yaml", text), f"{name}.yaml:4: knobs.{expected}")

    text = "spec: 1\ndevice: ms2000\nextends: mp285\n"
    add("other_family", _profile(directory, "family.yaml", text), "family.yaml:2: device: 'ms2000' cannot")
    text = 'spec: 1\nextends: ms2000\nversion: "USB-9.2k\\r\\n:A"\n'
    add(
        "bad_version",
        _profile(directory, "version.yaml", text),
        "version: 'USB-9.2k\\r\\n:A' is not printable",
    )
    text = f"spec: 1\nextends: ms2000\nversion: USB-{'9' * 40}\n"
    add("long_version", _profile(directory, "long.yaml", text), "is longer than 20 characters")
    text = 'spec: 1\ndevice: mp285\ndescription: "two\\nlines"\n'
    add(
        "two_line_description",
        _profile(directory, "two.yaml", text),
        "description: 'two\\nlines' is not one line",
    )

    keys = "".join(f"k{i}: 1\n" for i in range(10_000))
    _profile(directory, "wide.yaml", "spec: 1\ndevice: mp285\n" + keys)
    add(
        "wide_extends",
        _profile(directory, "x-wide.yaml", "spec: 1\nextends: wide.yaml\n" + keys),
        "unknown key",
    )
    return cases
