"""Ending a smoke run ends what it started (tests/support/process_group.py): its daemons used to
outlive a smoke run that was killed."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys

import pytest

from tests.support.process_group import end_group, start_group

#: only a hang takes this long
TIMEOUT_S = 10.0

#: a leader that starts a child, prints the child's pid and waits; "ignore" in its first argument
#: makes it ignore SIGTERM, in its second the child
LEADER = """
import signal, subprocess, sys, time
if sys.argv[1] == "ignore":
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
child = subprocess.Popen([sys.executable, "-c", sys.argv[3], sys.argv[2]])
print(child.pid, flush=True)
time.sleep(60)
"""
CHILD = """
import signal, sys, time
if sys.argv[1] == "ignore":
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
time.sleep(60)
"""

pytestmark = pytest.mark.skipif(not hasattr(os, "pidfd_open"), reason="needs pidfd_open (Linux)")


def leader_and_child(leader: str, child: str) -> tuple[subprocess.Popen[bytes], int]:
    """The leader, and a pidfd of its child (readable once the child has exited)."""
    proc = start_group([sys.executable, "-c", LEADER, leader, child, CHILD], stdout=subprocess.PIPE)
    assert proc.stdout is not None
    child = int(proc.stdout.readline())
    return proc, os.pidfd_open(child)


def exits(pidfd: int) -> bool:
    try:
        return bool(select.select([pidfd], [], [], TIMEOUT_S)[0])
    finally:
        os.close(pidfd)


def test_a_terminated_group_ends_whole() -> None:
    proc, child = leader_and_child("default", "default")
    end_group(proc, TIMEOUT_S)
    assert proc.returncode == -signal.SIGTERM
    assert exits(child)


def test_a_child_that_ignores_the_signal_is_killed_once_the_leader_has_exited() -> None:
    proc, child = leader_and_child("default", "ignore")
    end_group(proc, TIMEOUT_S)
    assert proc.returncode == -signal.SIGTERM
    assert exits(child)


def test_a_group_that_ignores_the_signal_is_killed_after_the_grace() -> None:
    proc, child = leader_and_child("ignore", "ignore")
    end_group(proc, 0.3)
    assert proc.returncode == -signal.SIGKILL
    assert exits(child)


def test_a_reaped_leader_is_left_alone() -> None:
    proc = start_group([sys.executable, "-c", "pass"])
    proc.wait()
    end_group(proc, TIMEOUT_S)  # its group number may be someone else's: nothing is signalled
    assert proc.returncode == 0
