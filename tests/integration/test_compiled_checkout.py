"""`make compile` (the last step of setup, and the first of every run, test, bench and soak) leaves a
process nothing to compile: with PYTHONDONTWRITEBYTECODE set, as on CI machines, an import reads the
.pyc it finds but never writes one, so without it every daemon compiled every module it imported
(3 s of a daemon's 8-11 s start on a loaded machine, issue "Fast, deterministic feedback")."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("emulator", "protocols", "configs")
#: what `make compile` compiles: the packages, and the scripts and tests whose daemons import them
COMPILED = (*PACKAGES, "scripts", "tests")

#: imports every module of the packages, recording each source file Python had to compile
PROBE = """
import json, pkgutil, sys
compiled = []
def hook(event, args):
    if event == "compile" and isinstance(args[1], str) and args[1].endswith(".py"):
        compiled.append(args[1])
sys.addaudithook(hook)
import emulator, protocols, configs
for package in (emulator, protocols, configs):
    assert package.__file__.startswith(sys.argv[1]), package.__file__
    for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
        __import__(info.name)
print(json.dumps(compiled))
"""


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make")
def test_make_compile_leaves_nothing_to_compile(tmp_path: Path) -> None:
    for tree in COMPILED:
        shutil.copytree(ROOT / tree, tmp_path / tree, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "Makefile", tmp_path)
    shutil.copy(ROOT / "pyproject.toml", tmp_path)
    # this test's own setup stamp, newer than pyproject.toml: make must not set up a .venv here
    os.utime(tmp_path / "pyproject.toml", (0, 0))
    stamp = tmp_path / "installed"
    stamp.touch()
    venv = Path(sys.prefix)
    make = ["make", "-C", str(tmp_path), "compile", f"VENV={venv}", f"STAMP={stamp}"]
    subprocess.run(make, capture_output=True, text=True, check=True)

    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    # the working directory comes first on sys.path: the copy, not the checkout the venv points at
    probe = [sys.executable, "-c", PROBE, str(tmp_path)]
    out = subprocess.run(probe, cwd=tmp_path, env=env, capture_output=True, text=True, check=True).stdout
    compiled = [path for path in json.loads(out) if path.startswith(str(tmp_path))]
    assert compiled == []


def test_make_test_leaves_pytest_no_test_module_to_rewrite(request: pytest.FixtureRequest) -> None:
    """`make test` collects once with writing allowed, so each pytest process of the run (the xdist
    workers, the smoke runs, the client suites) reads every test module's assert-rewritten .pyc
    instead of rewriting it (3.6 s of CPU per process here). A module changed since then is pytest's
    to rewrite, as always."""
    stamp = Path(sys.prefix) / ".tests-rewritten"
    if not stamp.exists():
        pytest.skip("the run was not started by `make test`")
    modules = {item.path for item in request.session.items} | set(ROOT.glob("tests/**/conftest.py"))
    unchanged = [path for path in modules if path.stat().st_mtime <= stamp.stat().st_mtime]
    missing = [path for path in unchanged if not rewritten_pyc(path).exists()]
    assert unchanged
    assert missing == []


def rewritten_pyc(path: Path) -> Path:
    """Where pytest keeps a module's assert-rewritten bytecode."""
    from _pytest.assertion.rewrite import PYC_TAIL

    return path.parent / "__pycache__" / (path.name[: -len(".py")] + PYC_TAIL)
