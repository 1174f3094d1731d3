"""TTL REPORT (§9.4) on a manual clock: frames on IN0 edges in mode 6 (MS-TTLREP-1…4), the overrun
rule, the knobs; the auxiliary port as rigs and the runner host it (MS-5)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest

from emulator.device import LOST, MAIN, DeviceServices, LineSettings
from emulator.devices.ms2000.model import Ms2000Device
from emulator.devices.ms2000.modules.ttl_report import AXIS_READ_S, FRAME_OVERHEAD_S, LATCH_S
from emulator.hosting.clock import ManualClock
from emulator.hosting.rig import load_rig, rig_from_profiles
from emulator.hosting.runner import DeviceRunner
from emulator.profiles.profile import ProfileError, load_profile
from emulator.profiles.registry import channels_of
from emulator.wire_time import REALISTIC
from protocols.ms2000 import ttl_report
from tests.support.memory_transport import MemoryTransport
from tests.unit.ms2000.conftest import Harness

TTLREP = "ms2000-ttlrep"
AUX = "aux"
#: X 1000 units, Y -505, Z 0 (as the vectors place them)
FRAME = b"\x18\xbc\x11\x00\x00\x19\x0c\xf7\xff\xff\x1a\x00\x00\x00\x00\x0d"
ZERO_FRAME = b"\x18\0\0\0\0\x19\0\0\0\0\x1a\0\0\0\0\r"
#: a 16-byte frame's busy time at 115200 baud (MS-TTLREP-3)
BUSY_S = 16 * 10 / 115200 + FRAME_OVERHEAD_S


def armed(
    make: Callable[..., Harness], overrides: dict | None = None, at: tuple[int, int] = (0, 0)
) -> Harness:
    """A TTL REPORT controller with X and Y at `at` (units), in IN0 mode 6."""
    h = make(TTLREP, overrides)
    if at != (0, 0):
        assert h.cmd(f"M X={at[0]} Y={at[1]}") == b":A\r\n"
        h.idle()
    assert h.cmd("TTL X=6") == b":A\r\n"
    h.take_emissions()
    h.take_received()
    return h


def pulse(h: Harness, after: float = 0.0) -> float:
    """An IN0 pulse `after` seconds from now; returns the edge's instant."""
    h.wait(after)
    h.input("ttl_in0", pulse_ms=0.1)
    return h.t


def test_edge_sends_one_frame_on_the_aux_port(make: Callable[..., Harness]) -> None:
    """MS-TTLREP-1, MS-TTLREP-2 on the model: the frame (id byte + int32 LSB first per axis, then
    CR) is latched 6 µs after the edge and handed to the aux UART after 12 µs per axis; its counts
    decode as the positions."""
    h = armed(make, at=(1000, -505))
    edge = pulse(h)
    h.wait(0.01)
    [emission] = h.take_emissions()
    assert (emission.channel, emission.data) == (AUX, FRAME)
    assert emission.due == pytest.approx(edge + LATCH_S + 3 * AXIS_READ_S)
    assert h.take_events("aux_tx")[0]["t"] == emission.due
    assert ttl_report.decode(FRAME).by_axis() == {"X": 4540, "Y": -2292, "Z": 0}


def test_frame_holds_the_encoder_counts_at_the_latch(make: Callable[..., Harness]) -> None:
    """MS-TTLREP-2: a moving axis reports where it was at the latch instant, relative to the origin."""
    h = armed(make)
    h.cmd("M X=100000")
    h.wait(0.2)
    edge = pulse(h)
    h.wait(0.01)
    axis = h.dev.axis_named("X")
    assert axis is not None
    latched = round(axis.user_mm(edge + LATCH_S) * axis.counts_per_mm)
    [emission] = [e for e in h.take_emissions() if e.channel == AUX]
    assert ttl_report.decode(emission.data).by_axis()["X"] == latched != 0


def test_ll_ids_follow_the_ll_setting(make: Callable[..., Harness]) -> None:
    """MS-TTLREP-2: the id byte is the axis's current low-level id (`LL`)."""
    h = armed(make)
    assert h.cmd("LL X=40") == b":A\r\n"
    pulse(h)
    h.wait(0.01)
    [emission] = h.take_emissions()
    assert [axis_id for axis_id, _ in ttl_report.decode(emission.data).positions] == [40, 0x19, 0x1A]


def test_edge_during_a_frame_overruns(make: Callable[..., Harness]) -> None:
    """MS-TTLREP-3 on the model: the overrun window is the frame's wire time + 0.11 ms to the
    tenth of a millisecond: an edge just inside it is dropped with code 87, one just after it is
    sent."""
    h = armed(make)
    first = pulse(h)
    pulse(h, BUSY_S - 0.0001)
    h.wait(0.01)
    assert len(h.take_emissions()) == 1
    assert h.cmd("DU Y") == b"87\r:A\r\n"
    h.wait(first + 0.02 - h.t)
    pulse(h)
    second = h.t
    pulse(h, BUSY_S + 0.0001)
    h.wait(0.01)
    assert [e.due - second for e in h.take_emissions() if e.channel == AUX] == pytest.approx(
        [LATCH_S + 3 * AXIS_READ_S, BUSY_S + 0.0001 + LATCH_S + 3 * AXIS_READ_S]
    )
    assert h.get("ttl_report") == {
        "port": AUX,
        "format": "binary",
        "frames": 3,
        "overruns": 1,
        "sending": False,
    }


def test_overrun_window_follows_the_baud_rate(make: Callable[..., Harness]) -> None:
    """MS-TTLREP-3, MS-5: at 9600 baud a frame keeps the port busy 16.8 ms."""
    h = armed(make, {"dip_switches": {"sw4": "up", "sw5": "up"}})
    pulse(h)
    pulse(h, 16 * 10 / 9600)  # still inside the 0.11 ms tail
    h.wait(0.05)
    assert len(h.take_emissions()) == 1
    assert list(h.dev.error_log) == [87]


def test_ascii_format_is_one_w_line(make: Callable[..., Harness]) -> None:
    """MS-TTLREP-4 on the model: the ASCII frame is one emission on the aux channel, the
    W-formatted positions with the current terminator."""
    h = armed(make, {"knobs": {"ttl_report_format": "ascii"}}, at=(1000, -505))
    pulse(h)
    h.wait(0.01)
    assert [(e.channel, e.data) for e in h.take_emissions()] == [(AUX, b"1000 -505 0\r\n")]
    assert h.cmd("VB X=8 Z=1") == b":A\r\n"
    where = h.cmd("W X Y Z")
    pulse(h, 0.01)
    h.wait(0.01)
    assert [e.data for e in h.take_emissions()] == [where.removeprefix(b":A ")]
    assert where.endswith(b"\r") and b"." in where


def test_main_port_variant_sends_frames_between_replies(make: Callable[..., Harness]) -> None:
    """MS-TTLREP-1, MS-18 (g): `ttl_report_port: main` has no auxiliary port; frames go out on the
    main port, unsolicited."""
    h = armed(make, {"knobs": {"ttl_report_port": "main"}}, at=(1000, -505))
    assert h.dev.channels == (MAIN,)
    pulse(h)
    h.wait(0.01)
    assert h.take_received() == FRAME
    assert h.take_events("aux_tx") == []


def test_mode_6_needs_the_module_and_the_interrupt(make: Callable[..., Harness]) -> None:
    """MS-90: mode 6 is `:N-4` without TTL REPORT, and without INO_INT."""
    assert make().cmd("TTL X=6") == b":N-4\r\n"
    h = make(TTLREP, {"modules": ["LL COMMANDS", "TTL REPORT"]})
    assert h.cmd("TTL X=6") == b":N-4\r\n"


def test_reset_abandons_a_frame_being_latched(make: Callable[..., Harness]) -> None:
    h = armed(make)
    h.input("ttl_in0", pulse_ms=0.1)
    h.cmd("~")
    h.wait(0.01)
    assert [e for e in h.take_emissions() if e.channel == AUX] == []
    assert h.get("ttl_report")["sending"] is False


def test_aux_port_only_transmits(make: Callable[..., Harness]) -> None:
    """MS-5: bytes a host writes to the auxiliary port are lost (noted), and its settings do not
    change the main port's host line."""
    h = armed(make)
    h.dev.explain = True
    h.call(lambda now: h.dev.receive(b"V\r", now, AUX))
    h.call(lambda now: h.dev.line_changed(LineSettings(9600, None, None, 1, False, False), now, AUX))
    assert h.take_emissions() == []
    assert [(n.kind, n.channel) for n in h.dev.take_rx_notes()] == [(LOST, AUX)]
    assert h.dev.host_line() is None
    assert h.cmd("V") == b":A Version: USB-9.2k \r\n"


# ---- the auxiliary port in rigs and the runner (MS-5) -------------------------------------------


def test_channels_come_from_the_profile() -> None:
    assert channels_of(load_profile(TTLREP)) == (MAIN, AUX)
    assert channels_of(load_profile(TTLREP, {"knobs": {"ttl_report_port": "main"}})) == (MAIN,)
    assert channels_of(load_profile("ms2000")) == (MAIN,)


def test_profile_option_adds_the_aux_port_next_to_the_main_link(tmp_path: Path) -> None:
    link = tmp_path / "ttyStage"
    [plain, linked] = rig_from_profiles([TTLREP, f"{TTLREP}:{link}"]).devices
    assert [(p.channel, p.link) for p in plain.ports] == [(MAIN, None), (AUX, None)]
    assert [(p.channel, p.link) for p in linked.ports] == [(MAIN, link), (AUX, tmp_path / "ttyStage.aux")]


def test_rig_ports_cover_every_channel(tmp_path: Path) -> None:
    """A rig that lists only the main port still gets the aux one; a channel the device lacks is an
    error."""
    rig = tmp_path / "rig.yaml"
    device = {"name": "stage", "profile": TTLREP, "ports": [{"link": "ttyStage", "timing": "fast"}]}
    rig.write_text(json.dumps({"spec": 1, "devices": [device]}))
    ports = load_rig(rig).devices[0].ports
    assert [(p.channel, p.link, p.timing) for p in ports] == [
        (MAIN, tmp_path / "ttyStage", "fast"),
        (AUX, tmp_path / "ttyStage.aux", None),
    ]
    rig.write_text(
        json.dumps({"spec": 1, "devices": [{**device, "profile": "ms2000", "ports": [{"channel": AUX}]}]})
    )
    with pytest.raises(ProfileError, match="device 'stage' has no channel 'aux' \\(it has: main\\)"):
        load_rig(rig)


def hosted(
    aux_limit: int | None = None,
) -> tuple[ManualClock, DeviceRunner, MemoryTransport, MemoryTransport]:
    clock = ManualClock()
    profile = load_profile(TTLREP)
    runner = DeviceRunner(lambda now: Ms2000Device("dut", profile, now, DeviceServices()), clock)
    main, aux = MemoryTransport(), MemoryTransport(output_limit=aux_limit)
    runner.attach_transport(MAIN, main, REALISTIC)
    runner.attach_transport(AUX, aux, REALISTIC)
    host = LineSettings(115200, None, None, 1, False, False)
    main.attach(host)
    aux.attach(host)
    main.send(b"TTL X=6\r")
    clock.advance(0.01)
    assert main.take() == b":A\r\n"
    return clock, runner, main, aux


def test_runner_paces_the_aux_port_at_the_main_baud() -> None:
    """MS-5, MS-TTLREP-2: the frame's 16 bytes take 1.39 ms at 115200 on the auxiliary port."""
    clock, runner, main, aux = hosted()
    char = 10 / 115200
    start = runner.call(lambda now: runner.device.control_input("ttl_in0", {"pulse_ms": 0.1}, now))
    due = clock.now() + LATCH_S + 3 * AXIS_READ_S
    received = []
    for chars in (2, 9):
        clock.advance(due + chars * char - clock.now())
        received.append(len(aux.written))
    assert received == [2, 9]
    clock.advance(0.01)
    assert aux.take() == ZERO_FRAME
    assert start is True and main.take() == b""


def test_aux_host_that_never_reads_blocks_nothing() -> None:
    """A full auxiliary port drops frames and counts them; the main port answers as before."""
    clock, runner, main, aux = hosted(aux_limit=64)
    for _ in range(10):
        runner.call(lambda now: runner.device.control_input("ttl_in0", {"pulse_ms": 0.1}, now))
        clock.advance(0.002)
    assert len(aux.written) == 64
    assert runner.channels[AUX].stats.output_dropped == 10 * 16 - 64
    main.send(b"V\r")
    clock.advance(0.01)
    assert main.take() == b":A Version: USB-9.2k \r\n"
    assert runner.channels[MAIN].stats.output_dropped == 0
