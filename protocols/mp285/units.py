"""MP-285 distance units: microsteps per micrometre by device type and the STEP fields (MP-28, MP-63)."""

from __future__ import annotations

# re-exported: MP-285 code rounds through this module (µm to µsteps, STEP fields, positions)
from protocols.rounding import round_half_away as round_half_away

#: microsteps per micrometre of X and Y by device type (Z: `z_usteps_per_um`, 25 unless customised)
XY_USTEPS_PER_UM = {"mp285": 25, "mt800": 20}
DEFAULT_Z_USTEPS_PER_UM = 25


def axis_factors(device_type: str, z_usteps_per_um: float = DEFAULT_Z_USTEPS_PER_UM) -> tuple[float, ...]:
    """µsteps per µm of X, Y, Z."""
    xy = XY_USTEPS_PER_UM[device_type]
    return (xy, xy, z_usteps_per_um)


def usteps_to_um(usteps: int, usteps_per_um: float) -> float:
    return usteps / usteps_per_um


def um_to_usteps(um: float, usteps_per_um: float) -> int:
    return round_half_away(um * usteps_per_um)


def step_fields(xy_usteps_per_um: int, fmt: str) -> tuple[int, int]:
    """STEP_DIV and STEP_MUL (MP-63): `mp285` = (µsteps/µm, µm/µstep × 100); `mp285a` = nm per 10
    µsteps, twice."""
    if fmt == "mp285":
        return xy_usteps_per_um, round_half_away(100 / xy_usteps_per_um)
    nm = round_half_away(10_000 / xy_usteps_per_um)
    return nm, nm
