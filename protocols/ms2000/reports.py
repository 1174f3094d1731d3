"""MS2000 text reports: the INFO (MS-106) and BU X (MS-102) layouts."""

from __future__ import annotations

#: each INFO row holds two items, the left one padded to this many characters
INFO_LEFT_WIDTH = 33
#: the BU X lines naming the motor axes (in hardware order, MS-29) and the command letters
BU_MOTOR_AXES = "Motor Axes:"
BU_CMDS = "CMDs:"


def parse_info(report: str) -> dict[str, str]:
    """An INFO report (rows separated by CR) as {label: value with units}."""
    result: dict[str, str] = {}
    for row in report.split("\r"):
        for item in (row[:INFO_LEFT_WIDTH], row[INFO_LEFT_WIDTH:]):
            label, sep, value = item.partition(":")
            if sep and label.strip():
                result[label.strip()] = value.strip()
    return result
