"""Identity, reports, the error log, non-volatile memory, reset and the LCD (§7): TV-93…TV-110,
TV-113."""

from __future__ import annotations

import contextlib
import json
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import pytest

from emulator.profiles.profile import load_profile
from emulator.urlhandler.control import HostedControl
from emulator.urlhandler.hosted import serve
from emulator.urlhandler.url import VIRTUAL, UrlOptions
from tests.conformance.conftest import Target
from tests.conformance.ms2000.conftest import ACK, IDLE, SILENT, VERSION, Host, Step
from tests.support.daemon import start_daemon

BU_X_LINES = [
    b"STD_XYZ",
    b"Motor Axes: X Y Z",
    b"CMDs: XYZFTR",
    b"BootLdr V:1",
    b"Hdwr REV.E",
    b"LL COMMANDS",
    b"RING BUFFER 50",
    b"INO_INT",
    b"LED DIMMER",
]

#: INFO X of the default profile at rest at the origin (MS-106); each row's left item is 33 wide
INFO_X_LINES = [
    b"Axis Name    :  X                Limits Status:  ",
    b"Input Device :      JS_X [J]     In_Dev Sign  :         1",
    b"Max Lim      :   110.000 [SU]    Min Lim      :  -110.000 [SL]",
    b"Ramp Time    :        70 (ms)[AC]Max Ramp Stps:        12",
    b"Run Speed    :   5.14560(mm/s)[S]vmax_enc     :      1401",
    b"Servo Lp Time:         6 (ms)    Ramp Length  :     15312 (enc)",
    b"dv_enc       :       116         LL Axis ID   :        24",
    b"Drift Error  :  0.000400 (mm)[E] enc_drift_err:        18",
    b"Finish Error :  0.000022 (mm)[PC}enc_finsh_err:         1",
    b"Backlash     :  0.040000 (mm)[B] enc_backlash :      1815",
    b"Kp           :       100 [KP]    Ki           :        20 [KI]",
    b"Kv           :        26 [KV]    Kd           :         0 [KD]",
    b"Axis Enable  :         3 [MC]    Motor Enable :         0",
    b"CMD_stat     :   NO_MOVE         Move_stat    :      IDLE",
    b"Current pos  :    0.0000 (mm)    enc position :         0",
    b"Target pos   :    0.0000 (mm)    enc target   :         0",
    b"enc pos error:         0         EEsum        :         0",
    b"Lst Stle Time:         0 (ms)    Av Settle Tim:         0 (ms)",
    b"Home position:   1000.00 (mm)    Motor Signal :       128 (DAC)",
    b"mm/sec/DAC_ct:   0.05500 [D]     Enc Cnts/mm  :  45396.00 [C]",
    b"Wait Time    :         0 [WT]    Button Enable:        31 [BE]",
]
INFO_X = b"\r".join(INFO_X_LINES) + b"\r\n"


def block(lines: list[bytes]) -> bytes:
    """A multi-line reply: lines separated by a bare CR, then CR LF (MS-15)."""
    return b"\r".join(lines) + b"\r\n"


VECTORS = [
    pytest.param([(b"BU\r", b"STD_XYZ\r\n")], id="tv093_build"),
    pytest.param([(b"BU X\r", block(BU_X_LINES))], id="tv094_build_modules", marks=pytest.mark.smoke),
    pytest.param(
        [
            (b"BU Y-\r", ACK),
            (b"BU Y=97\r", ACK),
            (b"BU Y=98\r", ACK),
            (b"BU Y?\r", b"ab\r\n"),
            (b"BU Y=127\r", b":N-4\r\n"),
            *[(b"BU Y=99\r", ACK)] * 18,
            (b"BU Y=99\r", b":N-4\r\n"),  # 20 characters at most
            (b"BU Y-\r", ACK),
            (b"BU Y?\r", b"\r\n"),
        ],
        id="tv096_user_string",
    ),
    pytest.param(
        [
            (b"BU Z?\r", b":A 0\r\n"),
            (b"BU Z-\r", ACK),
            (b"BU Z?\r", b":A 65535\r\n"),
            (b"BU Z+\r", ACK),
            (b"BU Z?\r", b":A 0\r\n"),
            (b"BU Z=70000\r", b":N-4\r\n"),
        ],
        id="tv097_volatile_counter",
    ),
    pytest.param([(b"N\r", b":A ASI-MS2000-XYBR-Zs-USB\r\n")], id="tv098_who"),
    pytest.param([(b"SS Z\r", ACK), (b"SS Q\r", b":N-2\r\n"), (b"SS\r", b":N-3\r\n")], id="tv104_saveset"),
    pytest.param(
        [
            (b"M X=1000\r", ACK),
            IDLE,
            (b"~\r", ACK),
            (b"W X Y Z\r", b":A 0 0 0\r\n"),
            (b"BU Z?\r", b":A 0\r\n"),
        ],
        id="tv108_reset",
    ),
]


@pytest.mark.parametrize("steps", VECTORS)
def test_tv_exchanges(ms: Host, steps: Sequence[Step]) -> None:
    """Each case is one test vector on the default profile, every reply byte for byte (MS-15,
    MS-31, MS-34, MS-101…MS-106, MS-110, MS-112)."""
    ms.run(steps)


#: half of the µm in which SU reads back, in encoder counts: how closely `Host.restart` can find a
#: real controller's power-up origin after a test moved it (the emulator's factory reset is exact)
ORIGIN_UNCERTAINTY_COUNTS = 23


def test_tv_099_info(ms: Host) -> None:
    """TV-99 (MS-106): INFO X byte for byte. On a real port the two encoder-count fields may be off
    by the uncertainty of the restored origin; everything else must match."""
    reply = ms.reply(b"I X\r")
    if ms.target.real:
        lines = reply.split(b"\r")
        for row, expected in enumerate(INFO_X_LINES):
            if b"enc position" not in expected and b"enc target" not in expected:
                continue
            head, _, counts = lines[row].rpartition(b":")
            assert abs(int(counts)) <= ORIGIN_UNCERTAINTY_COUNTS, lines[row]
            lines[row] = head + b":" + expected.rpartition(b":")[2]
        reply = b"\r".join(lines)
    assert reply == INFO_X


KNOB_VECTORS = [
    pytest.param(
        "ms2000",
        {"knobs": {"bu_x_ring_buffer_size": False}},
        [(b"BU X\r", block([b"RING BUFFER" if line == b"RING BUFFER 50" else line for line in BU_X_LINES]))],
        id="tv095_ring_buffer_line_without_size",
    ),
    pytest.param(
        "ms2000",
        {"knobs": {"info_fix_pc_tag": True}},
        [(b"I X\r", INFO_X.replace(b"(mm)[PC}", b"(mm)[PC]"))],
        id="tv100_info_fixed_tag",
    ),
    pytest.param(
        "ms2000-xy",
        None,
        [(b"INFO X\r", INFO_X), (b"INFO Z\r", b""), SILENT, (b"/\r", b"N\r\n")],
        id="tv101_absent",
    ),
    pytest.param(
        "ms2000-xy",
        {"knobs": {"info_absent_axis": "error"}},
        [(b"INFO Z\r", b":N-2\r\n")],
        id="tv102_absent_error",
    ),
]


@pytest.mark.parametrize(("profile", "overrides", "steps"), KNOB_VECTORS)
def test_tv_profile_exchanges(
    connect: Callable[..., Host], profile: str, overrides: dict[str, Any] | None, steps: Sequence[Step]
) -> None:
    """Vectors on another profile or knob setting (MS-102, MS-106, MS-107, MS-18)."""
    connect(profile, overrides).run(steps)


@pytest.mark.control
def test_tv_103_error_log(ms: Host) -> None:
    """TV-103 (MS-108, MS-41): `DU Y` lists the log newest first; `DU X` clears it."""
    ms.ask(b"DU Y\r", b":A\r\n")
    ms.input("log_error", code=87)
    ms.input("log_error", code=85)
    ms.run(
        [
            (b"DU Y\r", b"85\r87\r:A\r\n"),
            (b"DU X\r", ACK),
            (b"DU Y\r", b":A\r\n"),
            (b"DU F=999\r", ACK),
        ]
    )


@contextlib.contextmanager
def emulator_run(workdir: Path, virtual: bool) -> Iterator[Host]:
    """One run of the emulator serving the default profile, with its state directory in `workdir`:
    a device in this process in virtual time, or a daemon (`--target daemon`)."""
    profile = load_profile("ms2000")
    if virtual:
        hosted = serve(UrlOptions(profile="ms2000", time=VIRTUAL, state_dir=workdir))
        target = Target(
            hosted.url(), "ms2000", profile, False, "dut", HostedControl(hosted, "dut"), hosted=hosted
        )
        try:
            yield Host(target, target.open())
        finally:
            target.close()  # switches the device off: it saves what it keeps
        return
    rig = workdir / "rig.yaml"
    rig.write_text(json.dumps({"spec": 1, "devices": [{"name": "dut", "profile": "ms2000"}]}))
    daemon = start_daemon(workdir, [str(rig)], expect_ports=1)
    try:
        target = Target(daemon.port("dut"), "ms2000", profile, False, "dut", daemon.control())
        try:
            yield Host(target, target.open())
        finally:
            target.close()
    finally:
        daemon.stop()


@pytest.mark.control
def test_tv_105_saved_settings_survive_an_emulator_restart(
    request: pytest.FixtureRequest, tmp_path: Path
) -> None:
    """TV-105 (MS-111): `SS Z` settings survive a restart of the emulator (same `device_id`, same
    state directory); unsaved ones are lost at the next power cycle."""
    virtual = request.config.getoption("--target") == "virtual"
    with emulator_run(tmp_path, virtual) as host:
        host.run([(b"S X=3.3\r", ACK), (b"SS Z\r", ACK)])
    with emulator_run(tmp_path, virtual) as host:
        host.run([(b"S X?\r", b":A X=3.300000\r\n"), (b"S Y=2\r", ACK)])
        host.input("power_cycle")
        host.ask(b"S Y?\r", b":A Y=5.145600\r\n")


@pytest.mark.control
def test_tv_106_soft_limits_remembered_without_saving(ms: Host) -> None:
    """TV-106 (MS-111): SL is remembered as soon as it changes."""
    ms.ask(b"SL X=-50\r", ACK)
    ms.input("power_cycle")
    ms.ask(b"SL X?\r", b":A X=-50.000\r\n")


@pytest.mark.control
@pytest.mark.parametrize(
    ("orders", "reply"),
    [
        pytest.param([b"SS X\r"], b":A X=5.145600\r\n", id="factory_at_power_up"),
        pytest.param([b"SS X\r", b"SS Y\r"], b":A X=3.300000\r\n", id="cancelled"),
    ],
)
def test_tv_107_factory_reset_scheduled_and_cancelled(ms: Host, orders: list[bytes], reply: bytes) -> None:
    """TV-107 (MS-110, MS-112): `SS X` brings factory settings at the next power-up, and they stay at
    the one after; `SS Y` cancels it and the saved `S X=3.3` stays."""
    ms.run([(b"S X=3.3\r", ACK), (b"SS Z\r", ACK), *((order, ACK) for order in orders)])
    for _ in range(2):
        ms.input("power_cycle")
        ms.ask(b"S X?\r", reply)


@pytest.mark.control
def test_tv_109_positions_saved_at_power_off(ms: Host) -> None:
    """TV-109 (MS-113, MS-112): positions survive a power cycle unless `SP X=1`; then the origin is
    lost, not the stage's place (still 4540 counts from the old one)."""
    ms.run([(b"M X=1000\r", ACK), IDLE])
    ms.input("power_cycle")
    ms.run([(b"W X\r", b":A 1000\r\n"), (b"SP X=1\r", ACK), (b"SP X?\r", b":A X=1\r\n")])
    ms.input("power_cycle")
    ms.ask(b"W X\r", b":A 0\r\n")
    assert ms.axis("X")["machine_counts"] == 4540


@pytest.mark.control
def test_tv_110_savepos_alone_silences_until_power_cycle(ms: Host) -> None:
    """TV-110 (MS-113, MS-18): after bare `SP` answers, nothing is answered until a power cycle, not
    even a low-level read frame."""
    ms.run([(b"SP\r", ACK), (b"V\r", b""), (b"\xffB\x18a\x03:", b""), SILENT])
    ms.input("power_cycle")
    ms.ask(b"V\r", VERSION)


@pytest.mark.control
def test_tv_113_lcd_text_and_units(ms: Host) -> None:
    """TV-113 (MS-116): with DIP SW2 down the bottom line shows the quoted `LCD` text; unquoted
    text clears it; `UN` toggles units."""
    ms.input("dip", sw2="down")
    assert ms.get("lcd")[1] == "USB-9.2k"
    ms.ask(b'LCD "hello"\r', ACK)
    assert ms.get("lcd")[1] == "hello"
    ms.ask(b"LCD hello\r", ACK)
    assert ms.get("lcd")[1] == ""
    ms.ask(b"UN\r", ACK)
