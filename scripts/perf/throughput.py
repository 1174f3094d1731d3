"""Many ports on one daemon: aggregate round trips over busy ports, and what idle ports cost.

Busy: one daemon (`--timing fast`) with `ports` ports of one family, one host process per port
(forked from a server that imported this module, so 64 of them start in a moment), each doing round
trips through pyserial as fast as its replies come. A window counts the round trips completed between
its start and end; the hosts are told to go a lead time before the start, so the window sees steady
state. Visits alternate a window with only the first port busy and one with all of them; reported:
the median rates and, as the figure, the median over visits of each visit's all/one ratio. During a
visit the daemon runs on the least busy CPU and the hosts on the others (on one CPU, all together):
the rates are then the daemon's own, not the scheduler's choice of sharing a CPU with a host or not
(a single port's rate doubles when they share one, see scripts/perf/roundtrip.py).
Target (issue "Speed"): all ports together ≥ 0.9 × one busy port.

Idle: one daemon with `ports` ports (MP-285s and MS2000s, no host attached); its CPU use over a
window and its resident memory. Targets: CPU 0 % (bound 1 %), RSS < 60 MB.
"""

from __future__ import annotations

import multiprocessing
import statistics
import time
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from pathlib import Path

from emulator.hosting.launcher import write_rig
from protocols.mp285 import GetPosition, encode_position
from scripts.perf.common import (
    REPLY_TIMEOUT,
    BenchError,
    Check,
    Result,
    ask,
    open_host,
    placed,
    quietest_cpus,
    serve,
)
from scripts.soak.probes import cpu_percent, rss_mb

BUSY_RATIO = 0.9
IDLE_CPU_PERCENT = 1.0
IDLE_RSS_MB = 60.0
WARMUP = 20
#: between the signal to start and the window's start: every host is running by then
LEAD_S = 0.1

#: the round trip each family's hosts repeat: its name, the request and its exact reply
LOADS = {
    "ms2000": ("W X", b"W X\r", b":A 0\r\n"),
    "mp285": ("c", GetPosition().encode(), encode_position(0, 0, 0)),
}

Worker = tuple[BaseProcess, Connection]


def busy(workdir: Path, family: str, ports: int, window_s: float, visits: int) -> Result:
    label, request, reply = LOADS[family]
    names = [f"{family}{i}" for i in range(ports)]
    rig = write_rig(workdir, [(name, family) for name in names])
    daemon = serve(workdir, [str(rig), "--timing", "fast"], ports)
    context = multiprocessing.get_context("forkserver")
    # the server imports what the hosts need once; each host is then a bare fork (milliseconds)
    context.set_forkserver_preload([__name__])
    workers: list[Worker] = []
    try:
        for name in names:
            ours, theirs = context.Pipe()
            args = (daemon.port(name), request, reply, theirs)
            process = context.Process(target=_host, args=args, daemon=True, name=f"bench-{name}")
            process.start()
            theirs.close()  # the host's end lives in the host: its exit is then an EOF here
            workers.append((process, ours))
        for index, (_, conn) in enumerate(workers):
            _receive(conn, index, REPLY_TIMEOUT * 4)  # "ready": opened and warmed up
        one, every = [], []
        for _ in range(visits):
            cpus = quietest_cpus()
            hosts = set(cpus[1:]) or set(cpus)
            placement = {daemon.proc.pid: {cpus[0]}} | {host.pid: hosts for host, _ in workers if host.pid}
            with placed(placement):
                one.append(_window(workers[:1], window_s))
                every.append(_window(workers, window_s))
    finally:
        for host, conn in workers:
            conn.close()  # the host's recv() ends with EOFError: it closes its port and exits
            host.join(REPLY_TIMEOUT)
            if host.is_alive():
                host.kill()
        daemon.stop()
    ratios = [e / o for e, o in zip(every, one, strict=True)]
    return Result(
        case=f"throughput {ports} busy {family} ports ({label})",
        unit="rt/s",
        emulator=(statistics.median(every),),
        reference=(statistics.median(one),),
        checks=(Check(f"{ports} ports / 1 port", statistics.median(ratios), ">=", BUSY_RATIO),),
        details={"window_s": window_s, "visits": visits, "one_port": one, "all_ports": every},
    )


def idle(workdir: Path, ports: int, window_s: float) -> list[Result]:
    devices = [(f"{family}{i}", family) for i in range(ports // 2) for family in ("mp285", "ms2000")]
    daemon = serve(workdir, [str(write_rig(workdir, devices))], len(devices))
    try:
        cpu = cpu_percent(daemon.proc.pid, window_s)
        rss = rss_mb(daemon.proc.pid)
    finally:
        daemon.stop()
    return [
        Result(
            f"idle {len(devices)} ports: daemon CPU over {window_s:g} s",
            "%",
            (cpu,),
            (),
            (Check("CPU %", cpu, "<=", IDLE_CPU_PERCENT),),
        ),
        Result(
            f"idle {len(devices)} ports: daemon RSS",
            "MB",
            (rss,),
            (),
            (Check("RSS MB", rss, "<", IDLE_RSS_MB),),
        ),
    ]


def _window(workers: list[Worker], window_s: float) -> float:
    """Round trips per second completed by `workers` together over one window."""
    start = time.monotonic() + LEAD_S
    end = start + window_s
    for _, conn in workers:
        conn.send((start, end))
    total = sum(
        _receive(conn, index, end - time.monotonic() + REPLY_TIMEOUT)
        for index, (_, conn) in enumerate(workers)
    )
    return total / window_s


def _receive(conn: Connection, index: int, timeout: float) -> int:
    if not conn.poll(timeout):
        raise BenchError(f"host of port {index} silent for {timeout:.0f} s")
    try:
        message = conn.recv()
    except EOFError:
        raise BenchError(f"host of port {index} exited") from None
    if isinstance(message, BaseException):
        raise BenchError(f"host of port {index}: {message}")
    return int(message)


def _host(path: str, request: bytes, reply: bytes, conn: Connection) -> None:
    """One port's host process: opens the port, warms up, says so, then runs each window it is sent
    ((start, end) monotonic instants), answering with the round trips it completed inside it."""
    try:
        with open_host(path) as port:
            for _ in range(WARMUP):
                ask(port, request, reply)
            conn.send(0)
            while True:
                try:
                    start, end = conn.recv()
                except EOFError:
                    return
                count = 0
                while True:
                    ask(port, request, reply)
                    done = time.monotonic()
                    if done >= end:
                        break
                    count += done >= start
                conn.send(count)
    except Exception as error:  # the parent fails loudly with it
        conn.send(error)
