"""Start-up: how long a command takes from the shell, and a daemon until it is ready.

Each case is run `runs` times, the cases taking turns (so a machine's slow spells spread over all of
them), each a fresh process of the installed `stage-emu` script with PYTHONDONTWRITEBYTECODE=1 as on
CI machines (an import reads the .pyc that setup compiled but writes none). Timed from just before
the process is spawned:
  --version, ctl list   to its exit; `ctl list` asks a daemon started for the purpose
  serve                 to its last ready line on stdout (one per port): `--profile ms2000`, and the
                        bundled default rig (an MP-285 and an MS2000), each then stopped by SIGTERM
The reference is the same interpreter's own start (`python -c pass`), timed in the same turns.

Targets (issue "Fast, deterministic feedback", item 4), medians on a quiet 2-core machine:
`--version` and `ctl list` ≤ 0.15 s, `serve --profile ms2000` ≤ 0.3 s, the default rig ≤ 0.4 s.
They are absolute times: a slower or busier machine misses them without anything being wrong.
"""

from __future__ import annotations

import os
import selectors
import signal
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from scripts.perf.common import ROOT, BenchError, Check, Result, serve

#: a command that has not finished (or a daemon not ready) by then is broken, not slow
TIMEOUT_S = 20.0


@dataclass(frozen=True)
class Case:
    name: str
    args: tuple[str, ...]
    #: lines on stdout that mean ready (a daemon: one per port); 0: the command runs to its exit
    ready_lines: int
    target_s: float


CASES = (
    Case("stage-emu --version", ("--version",), 0, 0.15),
    Case("stage-emu ctl list", ("ctl", "list"), 0, 0.15),
    Case("stage-emu serve --profile ms2000: ready", ("serve", "--profile", "ms2000"), 1, 0.3),
    Case("stage-emu serve (default rig): ready", ("serve",), 2, 0.4),
)


def command() -> list[str]:
    """The installed `stage-emu` script beside this interpreter, as a user runs it."""
    script = Path(sys.executable).parent / "stage-emu"
    return [str(script)] if script.exists() else [sys.executable, "-m", "emulator.cli"]


def run(workdir: Path, runs: int) -> list[Result]:
    workdir.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    listed = serve(workdir / "listed", ["--profile", "mp285", "--no-state"], 1)
    try:
        control = ("--control", str(listed.control_path))
        times: dict[str, list[float]] = {case.name: [] for case in CASES}
        bare: list[float] = []
        for _ in range(runs):
            bare.append(_exit_time([sys.executable, "-c", "pass"], env))
            for index, case in enumerate(CASES):
                args = list(case.args)
                if case.args[0] == "ctl":
                    args[1:1] = control
                if case.ready_lines:
                    # the same directories every turn: from the second on, memory is read back, as
                    # a user's daemon does
                    args += _daemon_paths(workdir / f"case{index}")
                    log = workdir / f"case{index}.log"
                    times[case.name].append(_ready_time(command() + args, case.ready_lines, env, log))
                else:
                    times[case.name].append(_exit_time(command() + args, env))
    finally:
        listed.stop()
    reference = statistics.median(bare)
    return [_result(case, times[case.name], reference, runs) for case in CASES]


def _result(case: Case, seconds: list[float], bare_s: float, runs: int) -> Result:
    median = statistics.median(seconds)
    return Result(
        case=f"start-up {case.name}",
        unit="s",
        emulator=(median,),
        reference=(bare_s,),
        checks=(Check("median s", median, "<=", case.target_s),),
        details={"runs": runs, "seconds": seconds, "python_c_pass_s": bare_s},
        info=(("min s", min(seconds)), ("max s", max(seconds))),
    )


def _daemon_paths(workdir: Path) -> list[str]:
    """A daemon of its own: links, socket and memory in `workdir`, never the user's."""
    return [
        "--control",
        str(workdir / "control.sock"),
        "--link-dir",
        str(workdir / "links"),
        "--state-dir",
        str(workdir / "state"),
    ]


def _exit_time(argv: list[str], env: dict[str, str]) -> float:
    start = time.perf_counter()
    try:
        done = subprocess.run(argv, cwd=ROOT, env=env, capture_output=True, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        raise BenchError(f"`{' '.join(argv)}` still running after {TIMEOUT_S:g} s") from None
    elapsed = time.perf_counter() - start
    if done.returncode:
        said = (done.stderr.decode(errors="replace").strip().splitlines() or ["nothing"])[-1]
        raise BenchError(f"`{' '.join(argv)}` exited {done.returncode}: {said}")
    return elapsed


def _ready_time(argv: list[str], lines: int, env: dict[str, str], log: Path) -> float:
    """Seconds from spawning a daemon to its `lines`-th ready line; the daemon is then stopped. Its
    stderr goes to `log` (a pipe nobody reads could fill and stall it)."""
    with log.open("wb") as errors:
        start = time.perf_counter()
        proc = subprocess.Popen(argv, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=errors)
        try:
            _read_lines(proc, lines, argv)
            elapsed = time.perf_counter() - start
        except BenchError as exc:
            raise BenchError(f"{exc}; it said: {_last_line(log)}") from None
        finally:
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
            try:
                code = proc.wait(TIMEOUT_S)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
                raise BenchError(f"`{' '.join(argv)}` did not stop on SIGTERM in {TIMEOUT_S:g} s") from None
            finally:
                assert proc.stdout is not None
                proc.stdout.close()
    if code:
        raise BenchError(f"`{' '.join(argv)}` exited {code} when stopped: {_last_line(log)}")
    return elapsed


def _last_line(log: Path) -> str:
    return (log.read_text(errors="replace").strip().splitlines() or ["nothing"])[-1]


def _read_lines(proc: subprocess.Popen[bytes], count: int, argv: list[str]) -> None:
    assert proc.stdout is not None
    fd = proc.stdout.fileno()
    deadline = time.monotonic() + TIMEOUT_S
    seen = b""
    with selectors.DefaultSelector() as selector:
        selector.register(fd, selectors.EVENT_READ)
        while seen.count(b"\n") < count:
            remaining = deadline - time.monotonic()
            if remaining <= 0 or not selector.select(remaining):
                raise BenchError(f"`{' '.join(argv)}` not ready in {TIMEOUT_S:g} s")
            chunk = os.read(fd, 65536)
            if not chunk:
                raise BenchError(f"`{' '.join(argv)}` exited before it was ready")
            seen += chunk
