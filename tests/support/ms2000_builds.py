"""Profile overrides on `ms2000` for builds whose bundled profiles belong to later issues.

- `SEQ_LIKE`: `ms2000-seq` (STD_XYZ_SEQ, the Advanced Applications example) without SEQUENCER, which
  is not emulated yet: its other modules and X and Y on linear encoders at 100000 counts/mm.
- `PIEZO_LIKE`: `ms2000-pz-crisp` without CRISP: build PZ_CRISP, Z a ±50 µm piezo (655360 counts/mm,
  soft limits ∓0.05 mm, no backlash), modules LL COMMANDS, INO_INT, DAC OUT.
"""

from __future__ import annotations

from typing import Any

SEQ_MODULES = (
    "LL COMMANDS",
    "RING BUFFER",
    "SEARCH INDEX",
    "ARRAY MODULE",
    "INO_INT",
    "DAC OUT",
    "PLANAR CORRECTION",
)
LINEAR_XY = {
    "X": {"encoder": "linear", "counts_per_mm": 100000},
    "Y": {"encoder": "linear", "counts_per_mm": 100000},
}

SEQ_LIKE: dict[str, Any] = {
    "build_name": "STD_XYZ_SEQ",
    "modules": list(SEQ_MODULES),
    "axes": LINEAR_XY,
}
PIEZO_LIKE: dict[str, Any] = {
    "build_name": "PZ_CRISP",
    "modules": ["LL COMMANDS", "INO_INT", "DAC OUT"],
    "axes": {
        "Z": {
            "counts_per_mm": 655360,
            "soft_lower_mm": -0.05,
            "soft_upper_mm": 0.05,
            "travel_mm": [-0.05, 0.05],
            "backlash_mm": 0,
        }
    },
}
