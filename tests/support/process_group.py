"""A child process and everything it starts, ended together. The smoke runs' pytest processes start
daemons of their own: killing the pytest process alone left those daemons running for ever."""

from __future__ import annotations

import os
import select
import signal
import subprocess
from typing import Any


def start_group(command: list[str], **popen: Any) -> subprocess.Popen[bytes]:
    """`command` as the leader of a process group of its own, which its children join."""
    return subprocess.Popen(command, start_new_session=True, **popen)


def end_group(proc: subprocess.Popen[bytes], grace_s: float) -> None:
    """Terminate the whole group (a daemon stops cleanly on SIGTERM; SIGINT is no use here, as a
    background job's children inherit it ignored), then, once the leader has exited or `grace_s`
    has passed, kill what is left of the group: one may ignore SIGTERM or hang. A leader that has
    exited and been reaped is left alone: its group number may belong to someone else by now."""
    if proc.poll() is not None:
        return
    # from here on the leader is alive or an unreaped zombie, so the group number is still its own
    os.killpg(proc.pid, signal.SIGTERM)
    if hasattr(os, "pidfd_open"):
        leader = os.pidfd_open(proc.pid)
        try:
            select.select([leader], [], [], grace_s)  # readable once it has exited; still unreaped
        finally:
            os.close(leader)
    else:  # no way to wait without reaping: only a leader that outlives the grace gets the rest killed
        try:
            proc.wait(grace_s)
            return
        except subprocess.TimeoutExpired:
            pass
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
