"""Reading an MS2000's replies (the queries of emulator/tools/capture/ms2000.py) into profile fields.

A reply is taken in the shape the firmware gives it (MS-35): a settings query's values by axis
letter, in any of the four value shapes knob reply_shape_overrides can select, the shape itself
and its trailing space (MS-38) being readings too. What is not understood, and what does not
come, becomes a note; silence is an answer only to the two queries a knob may leave unanswered
(`I` of a letter that is not an axis, MS-107; an empty line, MS-8).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import Any

from emulator.devices.ms2000.modules import known_names
from emulator.profiles.profile import Profile
from emulator.tools.capture.ms2000 import (
    AXIS_SETTINGS,
    BUILD,
    CRISP_NAMES,
    EMPTY,
    RING_BUFFER,
    SWITCHES,
    VERSION,
    AxisSetting,
    not_an_axis,
    rest,
)
from emulator.tools.capture.readings import CaptureError, FieldPath, Query, Reading, Transcript
from emulator.tools.capture.wire import Wire
from protocols.ms2000 import (
    BU_CMDS,
    BU_MOTOR_AXES,
    CRLF,
    TRAILING_SPACE_SHAPES,
    ReplyKind,
    Shape,
    parse_info,
    parse_reply,
    query_shape,
)


def _modules_apart(actual: Any, observed: Any) -> int:
    """Modules one list has and the other has not (MS2000 builds differ by their modules)."""
    return len(set(actual or ()) ^ set(observed))


class Ms2000Reader:
    """Sends the queries and turns their replies into readings; what it does not understand, and
    what does not come, becomes a note."""

    def __init__(self, wire: Wire, transcript: Transcript) -> None:
        self.wire = wire
        self.transcript = transcript
        self.readings: list[Reading] = []
        #: the value replies' trailing spaces (MS-38), to tell knob reply_trailing_space
        self._trailing: list[bool] = []

    def add(self, path: FieldPath, value: Any, source: Query, **options: Any) -> None:
        self.readings.append(Reading(path, value, source.label, **options))

    def ask(self, query: Query, first: bool = False) -> str | None:
        """The reply's text without its CR LF; None (and a note) when it did not come complete."""
        data, complete = self.wire.until(query, CRLF)
        if complete:
            return data[: -len(CRLF)].decode("latin-1")
        if first and not data:
            raise CaptureError(
                f"{self.wire.port.name}: no reply to {query.label} at {self.wire.line.describe()} "
                f"within {self.wire.wait_for(query):.3g} s: wrong port, device or baud rate?"
            )
        self.transcript.no_reply(query, self.wire.wait_for(query), data)
        return None

    def read(self) -> list[Reading]:
        self.version(self.ask(VERSION, first=True))
        axes, modules = self.build(self.ask(BUILD))
        if not axes:
            self.transcript.note("per-axis settings not read: BU X named no motor axes")
        for switch, position in zip(("sw4", "sw5"), SWITCHES[self.wire.line.baud], strict=True):
            self.add(("dip_switches", switch), position, VERSION)
        absent = f"I {not_an_axis(axes)}"
        for query in rest(axes, modules):
            if query is EMPTY:  # MS-8
                self.knob_by_reply(query, "empty_line_reply", {":N-1": "error", None: "ignore"})
            elif query.label == absent:  # MS-107
                self.knob_by_reply(query, "info_absent_axis", {":N-2": "error", None: "silent"})
            else:
                reply = self.ask(query)
                if reply is not None:
                    self.answer(query, reply, axes)
        if self._trailing and len(set(self._trailing)) == 1:
            self.add(("knobs", "reply_trailing_space"), self._trailing[0], Query("value replies", b""))
        elif self._trailing:
            self.transcript.note("value replies end with a space only sometimes — not understood")
        return self.readings

    # ---- replies --------------------------------------------------------------------------------

    def answer(self, query: Query, reply: str, axes: Sequence[str]) -> None:
        """Dispatch a reply of `rest` by its command."""
        word = query.label.split(" ")[0]
        setting = next((s for s in AXIS_SETTINGS if s.key == word), None)
        if word == "CD":
            self.text_field(query, reply, ("cdate",), reply)
        elif word == "N":
            self.text_field(query, reply, ("who",), reply[3:] if reply.startswith(":A ") else "")
        elif word == "SB":
            values = self.values(query, reply, ("X",))
            if values is not None:
                self.number(query, reply, ("line", "stop_bits"), values["X"], integer=True)
        elif setting is not None:
            self.axis_setting(query, reply, setting, axes)
        elif word == "I":
            self.info(query, reply)
        elif word == "RB":
            self.rb(query, reply)
        elif word == "JS":
            self.knob_speeds(query, reply)

    def version(self, reply: str | None) -> None:
        """MS-99: `:A Version: <version>` and, by knob version_trailing_space, one space."""
        if reply is None:
            return
        match = re.fullmatch(r":A Version: (.+)", reply)
        text = "" if match is None else match.group(1).strip(" ")
        if match is None or not text or not text.isprintable():
            self.transcript.not_understood(VERSION, reply)
            return
        body = match.group(1)
        trailing = body.endswith(" ")
        self.add(("version",), body[:-1] if trailing else body, VERSION)
        self.add(("knobs", "version_trailing_space"), trailing, VERSION)

    def build(self, reply: str | None) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """MS-102: build name, `Motor Axes:`, `CMDs:`, boot loader, hardware, one line per module."""
        if reply is None:
            return (), ()
        lines = reply.split("\r")
        if len(lines) < 5 or not lines[1].startswith(BU_MOTOR_AXES) or not lines[2].startswith(BU_CMDS):
            self.transcript.not_understood(BUILD, reply)
            return (), ()
        axes = tuple(lines[1][len(BU_MOTOR_AXES) :].split())
        if not axes or not all(len(a) == 1 and "A" <= a <= "Z" for a in axes):
            self.transcript.not_understood(BUILD, reply)
            return (), ()
        self.add(("build_name",), lines[0], BUILD, weight=10)
        self.add(("motor_axes",), list(axes), BUILD, weight=1000)
        self.add(("cmd_letters",), lines[2][len(BU_CMDS) :].strip(" "), BUILD)
        self.add(("bootldr",), lines[3], BUILD)
        self.add(("hdwr",), lines[4], BUILD)
        modules = [name for line in lines[5:] if (name := self.module(line)) is not None]
        self.add(("modules",), modules, BUILD, weight=100, distance=_modules_apart)
        return axes, tuple(modules)

    def module(self, line: str) -> str | None:
        """A module line of BU X as the module's name in `modules`, its knobs as readings."""
        knobs = ("knobs",)
        if line in CRISP_NAMES:
            self.add((*knobs, "crisp_directive_name"), line, BUILD)
            return "CRISP"
        if line == RING_BUFFER:
            self.add((*knobs, "bu_x_ring_buffer_size"), False, BUILD)
            return line
        size = line[len(RING_BUFFER) + 1 :]
        if line.startswith(RING_BUFFER + " ") and size.isdigit():
            self.add((*knobs, "bu_x_ring_buffer_size"), True, BUILD)
            self.add(("ring_buffer_size",), int(size), BUILD)
            return RING_BUFFER
        if line in known_names():
            return line
        self.transcript.note(f"BU X lists the module {line!r}, which stage-emu does not emulate: left out")
        return None

    def text_field(self, query: Query, reply: str, path: FieldPath, value: str) -> None:
        if value and value.isprintable() and parse_reply(reply).kind is not ReplyKind.ERROR:
            self.add(path, value, query)
        else:
            self.transcript.not_understood(query, reply)

    def values(self, query: Query, reply: str, letters: Sequence[str]) -> dict[str, str] | None:
        """The `L=v` (or, in hardware order, positional) values of a settings query's reply, by
        letter, and its shape, which knob reply_shape_overrides may change (MS-35...MS-38)."""
        shape, found = _shape_and_values(reply, letters)
        if shape is None or found is None:
            self.transcript.not_understood(query, reply)
            return None
        key = query.label.split(" ")[0]
        self.add(
            ("knobs", "reply_shape_overrides", key),
            shape.value,
            query,
            observed=shape.value,
            actual=lambda profile: query_shape(key, profile.config.knobs.reply_shape_overrides).value,
        )
        if shape in TRAILING_SPACE_SHAPES:
            self._trailing.append(reply.endswith(" "))
        return found

    def number(self, query: Query, reply: str, path: FieldPath, text: str, integer: bool) -> None:
        value = float(text)
        if integer and not value.is_integer():
            self.transcript.not_understood(query, reply)
        else:
            self.add(path, int(value) if integer else value, query)

    def axis_setting(self, query: Query, reply: str, setting: AxisSetting, axes: Sequence[str]) -> None:
        values = self.values(query, reply, axes)
        if values is None:
            return
        for axis in axes:
            path = ("axes", axis, setting.field)
            if setting.key == "OS":
                self.overshoot(query, reply, axis, float(values[axis]))
            else:
                self.number(query, reply, path, values[axis], setting.integer)

    def overshoot(self, query: Query, reply: str, axis: str, reported: float) -> None:
        """MS-58: the controller keeps the overshoot in whole encoder counts and reports counts / C
        to 6 decimals; the profile gets a value that gives the same counts, compared as counts."""
        counts_per_mm = next(
            (r.value for r in self.readings if r.path == ("axes", axis, "counts_per_mm")), None
        )
        if counts_per_mm is None:
            self.transcript.note(f"{query.label}: {axis}'s overshoot not kept: C {axis}? was not read")
            return
        counts = round(reported * counts_per_mm)
        value = next(
            (v for v in (reported, round(reported + 1e-6, 6)) if int(v * counts_per_mm) == counts), None
        )
        if value is None:
            self.transcript.not_understood(query, reply)
            return
        self.add(
            ("axes", axis, "overshoot_mm"),
            value,
            query,
            observed=counts,
            actual=lambda profile: _overshoot_counts(profile, axis),
        )

    def info(self, query: Query, reply: str) -> None:
        """MS-106: the servo period and the finish error's tag, `[PC}` as the firmware prints it."""
        report = parse_info(reply)
        servo = re.fullmatch(r"(\d+) \(ms\)", report.get("Servo Lp Time", ""))
        finish = report.get("Finish Error", "")
        if servo is None or not finish.endswith(("[PC}", "[PC]")):
            self.transcript.not_understood(query, reply)
            return
        self.add(("servo_ms",), int(servo.group(1)), query)
        self.add(("knobs", "info_fix_pc_tag"), finish.endswith("[PC]"), query)

    def rb(self, query: Query, reply: str) -> None:
        """MS-82: `:A`, the raw status byte, by knob rb_space_after_ack a space between."""
        body = reply[2:] if reply.startswith(":A") else ""
        if len(body) == 1 or (len(body) == 2 and body[0] == " "):
            self.add(("knobs", "rb_space_after_ack"), len(body) == 2, query)
        else:
            self.transcript.not_understood(query, reply)

    def knob_speeds(self, query: Query, reply: str) -> None:
        """MS-KNOB-1: without XY KNOBS, `JS F?` is refused (`:N-2`) or answered."""
        parsed = parse_reply(reply)
        if parsed.kind is ReplyKind.ERROR and parsed.code == 2:
            self.add(("knobs", "knob_speeds_need_module"), True, query)
        elif parsed.kind is ReplyKind.VALUES and [name for name, _ in parsed.values] == ["KNOB_SLOW"]:
            self.add(("knobs", "knob_speeds_need_module"), False, query)
        else:
            self.transcript.not_understood(query, reply)

    def knob_by_reply(self, query: Query, knob: str, choices: dict[str | None, str]) -> None:
        """A knob told by which reply came, silence (None) being one of the answers."""
        data, complete = self.wire.until(query, CRLF)
        if data and not complete:
            self.transcript.no_reply(query, self.wire.wait_for(query), data)
            return
        reply = data[: -len(CRLF)].decode("latin-1") if complete else None
        if reply in choices:
            self.add(("knobs", knob), choices[reply], query)
        else:
            self.transcript.not_understood(query, data)


def _shape_and_values(reply: str, letters: Sequence[str]) -> tuple[Shape | None, dict[str, str] | None]:
    """The shape of a settings reply and its values by axis letter (None when it is neither)."""
    parsed = parse_reply(reply)
    if parsed.kind is not ReplyKind.VALUES:
        return None, None
    core = reply.strip(" ")
    if parsed.values:
        found = dict(parsed.values)
        if sorted(found) != sorted(letters) or len(parsed.values) != len(letters):
            return None, None
        if core.startswith(":A "):
            return Shape.A_AXIS, found
        return (Shape.COLON_AXIS_A if core.startswith(":") else Shape.AXIS_COLON_A), found
    numbers = parsed.numbers
    if len(numbers) != len(letters) or not all(_is_number(n) for n in numbers):
        return None, None
    return Shape.A_LIST, dict(zip(letters, numbers, strict=True))


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _overshoot_counts(profile: Profile[Any], axis: str) -> int | None:
    """What the controller built from `profile` keeps as the overshoot of `axis` (MS-58)."""
    entry = profile.config.axes.get(axis)
    return None if entry is None else int(entry.overshoot_mm * entry.counts_per_mm)
