"""Short fixed forms of the torture suite's attacks (scripts/torture.py runs them at full length).

Timing ratios are figures of the soak run, not assertions here: a shared CI machine would make them
flaky. What is asserted is what must hold on any machine: bounded memory, no leaked descriptors,
correct answers during and after the attack."""

from __future__ import annotations

from pathlib import Path

import pytest

from scripts.soak import attacks, probes, starvation

#: the idle-CPU figure's sampling window here: a figure of the soak (2 s windows there, where it is
#: bounded), not asserted by these short forms, so a short window keeps them short
CPU_SAMPLE_S = 0.1


@pytest.fixture
def short_cpu_samples(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(attacks, "cpu_percent", lambda pid, _seconds: probes.cpu_percent(pid, CPU_SAMPLE_S))


@pytest.mark.usefixtures("short_cpu_samples")
def test_flood_of_random_bytes_is_held_to_the_wire_rate(tmp_path: Path) -> None:
    out = attacks.flood(tmp_path, seconds=2, flooded=3, idle_trips=30)
    timing = {f"other port's p99 > {attacks.P99_RATIO}x idle"}
    assert set(out.exceeded) <= timing, out.figures
    assert out.figures["rss_after_mb"] - out.figures["rss_before_mb"] < attacks.RSS_GROWTH_MB


def test_network_clients_flooding_without_reading_are_held_to_the_wire_rate(tmp_path: Path) -> None:
    out = attacks.network_flood(tmp_path, seconds=2, idle_trips=30)
    timing = {f"other port's p99 > {attacks.P99_RATIO}x idle"}
    assert set(out.exceeded) <= timing, (out.exceeded, out.figures)
    assert out.figures["bytes_accepted"] > 0, out.figures


@pytest.mark.usefixtures("short_cpu_samples")
def test_open_close_cycles_leak_nothing(tmp_path: Path) -> None:
    out = attacks.open_close(tmp_path, cycles=150)
    assert out.figures["fds_after"] == out.figures["fds_before"], out.figures
    assert out.figures["rss_after_mb"] - out.figures["rss_before_mb"] < 2.0, out.figures


def test_subscriber_that_never_reads_costs_bounded_memory(tmp_path: Path) -> None:
    out = attacks.slow_subscriber(tmp_path, seconds=2)
    assert out.passed, (out.exceeded, out.figures)
    assert out.figures["events_published"] > 100, out.figures


def test_devices_that_cannot_keep_up_fall_behind_instead_of_holding_the_daemon(tmp_path: Path) -> None:
    """Three devices with more work than the CPU can do at time scale 10 000: before, the loop
    stopped turning (no neighbour, no control channel, SIGTERM ignored, memory growing)."""
    run = starvation.starve(tmp_path, seconds=2)
    assert len(run.neighbour.samples) > 10 and len(run.control.samples) > 10
    assert all(behind > 0 for behind in run.behind_s.values()), run.behind_s
    assert run.lag_warnings == len(starvation.LOADS)
    assert run.rss_after_mb - run.rss_before_mb < starvation.RSS_GROWTH_MB
    assert run.exit_code == 0
