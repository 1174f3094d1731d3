"""Capturing a Sutter MP-285 / MP-285A: the status block and how the port answers a lone CR.

Two things are sent, nothing else (`is_read_only`): `s` (`73 0D`, MP-60), whose 32 bytes hold the
power-on settings, the `V` word in force and the firmware version, and one CR in command
position (`0D`, MP-20), answered with a CR or not at all. The interface and line settings are how
the port was opened (`--rtscts`: the MP-285A's USB virtual COM port, MP-2). Neither command moves,
stores or resets anything; both interrupt a move (MP-51), so capture a controller at rest.
"""

from __future__ import annotations

from typing import Any

from emulator.devices.mp285.schema import BAUDS
from emulator.devices.mp285.status import Status
from emulator.profiles.profile import Profile
from emulator.tools.capture.readings import CaptureError, Query, Reading, Transcript
from emulator.tools.capture.wire import LineOptions, Wire
from protocols import mp285 as proto

NAME = "mp285"
STATUS = Query("s", proto.GetStatus().encode(), proto.STATUS_REPLY_LENGTH)
LONE_CR = Query("CR", bytes([proto.CR]), 1)
#: bytes 0-23 of the status block come from the profile's template (24-31 are computed, MP-60)
TEMPLATE_BYTES = 24
#: MP-63: the STEP fields each device type and format give, and back
STEP_FIELDS = {
    proto.step_fields(per_um, fmt): (device, fmt)
    for device, per_um in proto.XY_USTEPS_PER_UM.items()
    for fmt in ("mp285", "mp285a")
}


def line_problem(line: LineOptions) -> str | None:
    """Why the MP-285 cannot be opened at `line` (MP-1, MP-2), or None."""
    if line.baud not in BAUDS:
        return f"--baud {line.baud}: the MP-285 runs at {', '.join(map(str, BAUDS))} (MP-1)"
    if line.rtscts and (line.baud, line.parity, line.stop_bits) != (9600, "none", 1):
        return "--rtscts is the MP-285A's USB port, fixed at 9600 8N1 (MP-2)"
    return None


def plan() -> list[Query]:
    return [STATUS, LONE_CR]


DRY_RUN_NOTES = ("bytes in hex: `s` then a lone CR; nothing else is sent",)


def is_read_only(query: Query) -> bool:
    return query.wire in (STATUS.wire, LONE_CR.wire)


def power_on_block(profile: Profile[Any]) -> bytes:
    """The status block a controller built from `profile` reports at power-on (MP-60...MP-65)."""
    cfg = profile.config
    velocity = proto.Velocity.from_word(cfg.controller.power_on_velocity_word)
    return Status(cfg.controller, cfg.stage, cfg.knobs).block(False, velocity).pack()


def _template_part(profile: Profile[Any]) -> bytes:
    return power_on_block(profile)[:TEMPLATE_BYTES]


def _bytes_apart(actual: Any, observed: Any) -> int:
    return sum(a != b for a, b in zip(actual, observed, strict=True))


class Mp285Reader:
    def __init__(self, wire: Wire, transcript: Transcript) -> None:
        self.wire = wire
        self.transcript = transcript
        self.readings: list[Reading] = []

    def add(self, path: tuple[str, ...], value: Any, source: str, **options: Any) -> None:
        self.readings.append(Reading(path, value, source, **options))

    def read(self) -> list[Reading]:
        line = self.wire.line
        self.add(("line", "baud"), line.baud, "--baud")
        self.add(("line", "parity"), line.parity, "--parity")
        self.add(("line", "stop_bits"), line.stop_bits, "--stop-bits")
        self.add(("line", "flow_control"), "rtscts" if line.rtscts else "none", "--rtscts")
        interface = "usb_vcp" if line.rtscts else "rs232"
        self.add(("controller", "interface"), interface, "--rtscts", weight=1000)
        self.status(self.wire.count(STATUS, proto.STATUS_REPLY_LENGTH))
        self.lone_cr(self.wire.count(LONE_CR, 1))
        return self.readings

    def status(self, data: bytes) -> None:
        """MP-60: the template's bytes, the STEP fields (MP-63), XSPEED (MP-61) and VERSION."""
        if not data:
            raise CaptureError(
                f"{self.wire.port.name}: no reply to s at {self.wire.line.describe()} within "
                f"{self.wire.wait_for(STATUS):.3g} s: wrong port, device or baud rate?"
            )
        if len(data) < proto.STATUS_REPLY_LENGTH:
            self.transcript.no_reply(STATUS, self.wire.wait_for(STATUS), data)
            return
        if data[-1] != proto.CR:
            self.transcript.not_understood(STATUS, data.hex(" "))
            return
        block = proto.StatusBlock.unpack(data)
        source = STATUS.label
        self.add(
            ("controller", "status_template"),
            data[:-1].hex(" ").upper(),
            source,
            observed=data[:TEMPLATE_BYTES],
            actual=_template_part,
            distance=_bytes_apart,
        )
        self.add(("controller", "firmware_version"), block.version, source)
        self.add(("controller", "power_on_velocity_word"), block.xspeed, source)
        kind = STEP_FIELDS.get((block.step_div, block.step_mul))
        if kind is None:
            self.transcript.note(
                f"s: STEP_DIV/STEP_MUL {block.step_div}/{block.step_mul} — not understood "
                "(neither device type in either format, MP-63)"
            )
        else:
            self.add(("stage", "device_type"), kind[0], source)
            self.add(("controller", "step_fields_format"), kind[1], source)

    def lone_cr(self, data: bytes) -> None:
        """MP-20: a lone CR is answered with a CR, or ignored."""
        if data in (b"", bytes([proto.CR])):
            self.add(("knobs", "stray_terminator_reply"), "cr" if data else "ignore", LONE_CR.label)
        else:
            self.transcript.not_understood(LONE_CR, data.hex(" "))


def caveats(parent: Profile[Any]) -> list[str]:
    """What the header says of the fields a capture cannot read or reads only as they are now."""
    controller = parent.config.controller
    return [
        f"The model is not readable: {parent.name}'s {controller.model} (low-resolution limit "
        f"{controller.max_speed_low_um_s} µm/s, MP-38).",
        "power_on_velocity_word is the V word in force when read: the power-on one if no host sent V",
        "since the controller was switched on or reset (MP-61).",
    ]
