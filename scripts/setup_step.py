"""One step of `make`'s .venv setup: run a pip command, keep its full output in a log, and print a
few lines of progress instead (the Makefile's setup used to be two silent minutes on a fresh
machine).

    python scripts/setup_step.py LOG "[3/4] installing stage-emu" python -m pip install -e .

Prints `stage-emu: LABEL`, then one indented line each time pip moves on to another phase
(collecting, building, installing), a `still ...` line when a phase has been quiet for
`HEARTBEAT_S`, and a closing line with the step's time. pip's output is appended to LOG and, if the
command fails, printed in full with one closing line (exit status 1).

Standard library only: it runs in the new .venv before anything else is installed there.
"""

from __future__ import annotations

import queue
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

PREFIX = "stage-emu: "
INDENT = PREFIX + "      "
#: a phase that prints nothing for this long gets a `still ...` line
HEARTBEAT_S = 15.0
#: names shown on one `collecting` line at most (the count says the rest)
SHOWN_NAMES = 6


@dataclass
class Progress:
    """pip's output, line by line, condensed to the phase it is in and what it has done so far."""

    phase: str = ""
    collected: list[str] = field(default_factory=list)
    satisfied: int = 0
    installed: int = 0
    changed_at: float = 0.0  # when the current phase began
    said_at: float = 0.0  # when a line last said so

    def feed(self, line: str, now: float) -> list[str]:
        """The progress lines `line` of pip's output calls for (often none)."""
        words = line.split()
        if not words:
            return []
        if words[0] in ("Collecting", "Processing") and len(words) > 1:
            self.collected.append(_package(words[1]))
            return self._enter("collecting", now)
        if words[:3] == ["Installing", "build", "dependencies:"]:
            return self._enter("preparing", now, "preparing the build...")
        if words[:3] == ["Requirement", "already", "satisfied:"]:
            self.satisfied += 1
            return []
        if words[0] == "Building" and len(words) > 1 and words[1] in ("wheel", "wheels", "editable"):
            return self._enter("building", now)
        if words[:3] == ["Installing", "collected", "packages:"]:
            count = len(line.split(":", 1)[1].split(","))
            return self._enter("installing", now, f"installing {count} package{'s' * (count != 1)}")
        if words[:2] == ["Successfully", "installed"]:
            self.installed = len(words) - 2
        return []

    def tick(self, now: float) -> list[str]:
        """A `still ...` line when the current phase has gone HEARTBEAT_S without one."""
        if not self.phase or now - self.said_at < HEARTBEAT_S:
            return []
        self.said_at = now
        so_far = f"{self._count()} so far, " if self.phase == "collecting" else ""
        return [f"still {self.phase} ({so_far}{now - self.changed_at:.0f} s)"]

    def summary(self, seconds: float) -> str:
        done = [f"{self.installed} installed"] if self.installed else []
        if self.satisfied:
            done.append(f"{self.satisfied} already there")
        return f"done in {seconds:.0f} s" + (f": {', '.join(done)}" if done else "")

    def _enter(self, phase: str, now: float, text: str = "") -> list[str]:
        if phase == self.phase:
            return []
        lines = [f"collected {self._so_far()}"] if self.phase == "collecting" else []
        self.phase, self.changed_at, self.said_at = phase, now, now
        if phase == "collecting":
            return [*lines, "collecting packages..."]
        return [*lines, text or f"{phase}..."]

    def _count(self) -> str:
        count = len(self.collected)
        return f"{count} package{'s' * (count != 1)}"

    def _so_far(self) -> str:
        """The count and the first names (the direct requirements, which pip collects first)."""
        names = self.collected[:SHOWN_NAMES]
        more = ", …" if len(self.collected) > SHOWN_NAMES else ""
        return self._count() + (f": {', '.join(names)}{more}" if names else "")


def _package(requirement: str) -> str:
    """`pytest>=7` -> `pytest`; `/wheels/matplotlib-3.9.0-cp311-...whl` -> `matplotlib`."""
    if "/" in requirement or requirement.endswith((".whl", ".tar.gz", ".zip")):
        return requirement.rsplit("/", 1)[-1].split("-")[0]
    for mark in "<>=!~[;(@ ":
        requirement = requirement.split(mark, 1)[0]
    return requirement


def run(label: str, command: list[str], log: Path, out: TextIO, clock: Callable[[], float]) -> int:
    """Run `command`, progress on `out`, its output appended to `log`; its exit status."""
    print(f"{PREFIX}{label}", file=out, flush=True)
    start = clock()
    progress = Progress(changed_at=start, said_at=start)
    lines: queue.Queue[str | None] = queue.Queue()
    with log.open("a", encoding="utf-8") as sink:
        sink.write(f"$ {' '.join(command)}\n")
        sink.flush()
        try:
            child = subprocess.Popen(
                command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, errors="replace"
            )
        except OSError as exc:
            sink.write(f"{exc}\n")
            return 127
        assert child.stdout is not None
        reader = threading.Thread(target=_pump, args=(child.stdout, lines), daemon=True)
        reader.start()
        while True:
            try:
                line = lines.get(timeout=1.0)
            except queue.Empty:
                line = ""
            if line is None:
                break
            sink.write(line)
            for text in progress.feed(line, clock()) + progress.tick(clock()):
                print(f"{INDENT}{text}", file=out, flush=True)
        status = child.wait()
    if status == 0:
        print(f"{INDENT}{progress.summary(clock() - start)}", file=out, flush=True)
    return status


def _pump(stream: TextIO, lines: queue.Queue[str | None]) -> None:
    for line in stream:
        lines.put(line)
    lines.put(None)


def main(argv: list[str]) -> int:
    if len(argv) < 3:
        print("usage: setup_step.py LOG LABEL COMMAND...", file=sys.stderr)
        return 2
    log = Path(argv[0])
    status = run(argv[1], argv[2:], log, sys.stderr, time.monotonic)
    if status != 0:
        sys.stderr.write(log.read_text(encoding="utf-8", errors="replace"))
        print(f"{PREFIX}setup failed (log above, also in {log})", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
