"""`make`'s .venv setup (scripts/setup_step.py): a line per step and pip's progress condensed, pip's
full output kept in the log and shown only when a step fails (issue "Hardening, round two")."""

from __future__ import annotations

import io
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from scripts.setup_step import HEARTBEAT_S, Progress, main, run

ROOT = Path(__file__).resolve().parents[2]

PIP_OUTPUT = """\
Looking in indexes: https://pypi.org/simple
Obtaining file:///work/main
  Installing build dependencies: started
  Installing build dependencies: finished with status 'done'
Processing /opt/pypi/files/pyserial-3.5-py2.py3-none-any.whl (from stage-emu==0.1.0)
Collecting click>=8.0 (from stage-emu==0.1.0)
  Downloading click-8.5.1-py3-none-any.whl (126 kB)
Collecting pyyaml>=6.0 (from stage-emu==0.1.0)
Requirement already satisfied: pip in ./.venv/lib/python3.11/site-packages (26.3)
Building wheels for collected packages: stage-emu
  Building editable for stage-emu (pyproject.toml): started
Installing collected packages: pyserial, pyyaml, click, stage-emu
Successfully installed click-8.5.1 pyserial-3.5 pyyaml-6.0.4 stage-emu-0.1.0
"""


def feed_all(progress: Progress, text: str) -> list[str]:
    return [said for line in text.splitlines(keepends=True) for said in progress.feed(line, 0.0)]


def test_pip_output_is_condensed_to_its_phases() -> None:
    progress = Progress()
    assert feed_all(progress, PIP_OUTPUT) == [
        "preparing the build...",
        "collecting packages...",
        "collected 3 packages: pyserial, click, pyyaml",
        "building...",
        "installing 4 packages",
    ]
    assert progress.summary(12.4) == "done in 12 s: 4 installed, 1 already there"


def test_a_long_quiet_phase_says_it_is_still_going() -> None:
    progress = Progress()
    progress.feed("Collecting pytest>=7\n", 100.0)
    assert progress.tick(100.0 + HEARTBEAT_S - 1) == []
    assert progress.tick(100.0 + HEARTBEAT_S) == [f"still collecting (1 package so far, {HEARTBEAT_S:.0f} s)"]
    assert progress.tick(100.0 + HEARTBEAT_S + 1) == []  # once per HEARTBEAT_S
    progress.feed("Installing collected packages: pytest\n", 200.0)
    assert progress.tick(200.0 + 2 * HEARTBEAT_S) == [f"still installing ({2 * HEARTBEAT_S:.0f} s)"]


def test_a_step_prints_progress_and_logs_everything(tmp_path: Path) -> None:
    log = tmp_path / "setup.log"
    out = io.StringIO()
    script = "print('Collecting click>=8'); print('Installing collected packages: click')"
    assert run("[3/4] installing", [sys.executable, "-c", script], log, out, lambda: 0.0) == 0
    assert out.getvalue().splitlines() == [
        "stage-emu: [3/4] installing",
        "stage-emu:       collecting packages...",
        "stage-emu:       collected 1 package: click",
        "stage-emu:       installing 1 package",
        "stage-emu:       done in 0 s",
    ]
    assert "Collecting click>=8\nInstalling collected packages: click\n" in log.read_text()


def test_a_failed_step_shows_the_whole_log(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "setup.log"
    log.write_text("earlier step\n")
    script = "import sys; print('ERROR: No matching distribution found for nothing'); sys.exit(3)"
    assert main([str(log), "[4/4] installing", sys.executable, "-c", script]) == 1
    err = capsys.readouterr().err.splitlines()
    assert err[0] == "stage-emu: [4/4] installing"
    assert "earlier step" in err and "ERROR: No matching distribution found for nothing" in err
    assert err[-1] == f"stage-emu: setup failed (log above, also in {log})"


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make")
def test_the_makefile_runs_each_step_through_the_script() -> None:
    plan = subprocess.run(
        ["make", "-n", "-B", ".venv/.installed"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout
    steps = [line for line in plan.splitlines() if "scripts/setup_step.py .venv/setup.log" in line]
    assert [line.split('"')[1] for line in steps] == [
        "[2/5] upgrading pip",
        "[3/5] installing stage-emu and its run-time dependencies",
        "[4/5] installing the test extra (pytest, hypothesis, ruff, mypy, microscope, matplotlib)",
        "[5/5] byte-compiling stage-emu",
    ]
    assert "pip install --disable-pip-version-check -e '.[test]'" in plan
    assert steps[-1].endswith(COMPILE)


#: what setup ends with and every run, test, bench and soak starts with (plain .pyc, by timestamp)
COMPILE = "-m compileall -q --invalidation-mode timestamp emulator protocols configs scripts tests"


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make")
@pytest.mark.parametrize(
    ("target", "command"),
    [
        ("run", "stage-emu serve"),
        ("test", "ruff check"),
        ("bench", "scripts/bench.py"),
        ("soak", "scripts/torture.py"),
    ],
)
def test_every_run_first_compiles_what_changed(target: str, command: str) -> None:
    """A changed .py is compiled once by make, not by every process that imports it (with
    PYTHONDONTWRITEBYTECODE set, as on CI machines, no import writes the .pyc)."""
    plan = subprocess.run(["make", "-n", target], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    lines = plan.splitlines()
    compiled = [i for i, line in enumerate(lines) if line == f".venv/bin/python {COMPILE}"]
    ran = next(i for i, line in enumerate(lines) if command in line)
    assert compiled and compiled[-1] < ran, plan


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make")
def test_clean_removes_the_compiled_files() -> None:
    plan = subprocess.run(
        ["make", "-n", "clean"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout
    assert "find . -name __pycache__ -type d -prune -exec rm -rf {} +" in plan
