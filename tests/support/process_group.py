"""A child process and everything it starts, ended together. The smoke runs' pytest processes start
daemons of their own: killing the pytest process alone left those daemons running for ever."""

from __future__ import annotations

import os
import signal
import subprocess
from typing import Any


def start_group(command: list[str], **popen: Any) -> subprocess.Popen[bytes]:
    """`command` as the leader of a process group of its own, which its children join."""
    return subprocess.Popen(command, start_new_session=True, **popen)


def end_group(proc: subprocess.Popen[bytes], grace_s: float) -> None:
    """Interrupt the whole group (pytest tears its fixtures down, a daemon stops cleanly), then kill
    what is left of it if the leader has not exited within `grace_s`. A leader that has exited and
    been reaped is left alone: its process group number may belong to someone else by now."""
    if proc.poll() is not None:
        return
    # the leader is alive or an unreaped zombie, so the group number is still its own
    os.killpg(proc.pid, signal.SIGINT)
    try:
        proc.wait(grace_s)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
