"""A value refused for being out of range is shown as it was given: one just past a bound never reads
as the bound itself (`got 10000` for 10000.0001), and a bound is never shown rounded either."""

from __future__ import annotations

import pytest

from emulator.hosting.clock import MAX_SCALE, MAX_STEP, MIN_SCALE, ScaledClock, check_scale, check_step
from emulator.hosting.port_faults import fault_params
from emulator.profiles.schema import Int, SchemaError, show_number
from protocols.mp285 import INT32_MAX


@pytest.mark.parametrize(
    ("value", "text"),
    [
        (10000.0, "10000"),
        (10000.0001, "10000.0001"),
        (3600.0001, "3600.0001"),
        (0.001, "0.001"),
        (0.00099999, "0.00099999"),
        (1e6, "1e+06"),  # short where short is exact, as before
        (1e300, "1e+300"),
        (INT32_MAX, "2147483647"),
        (10**400, "1" + "0" * 400),  # an integer past the float range (JSON allows it)
    ],
)
def test_show_number_is_short_only_where_short_is_exact(value: float, text: str) -> None:
    assert show_number(value) == text


@pytest.mark.parametrize(
    ("check", "value", "message"),
    [
        (check_scale, MAX_SCALE + 0.0001, "time scale must be between 0.001 and 10000, got 10000.0001"),
        (check_scale, 0.00099999, "time scale must be between 0.001 and 10000, got 0.00099999"),
        (check_step, MAX_STEP + 0.0001, "step must be between 0 and 3600 s, got 3600.0001"),
    ],
)
def test_clock_limits_show_the_value_as_given(check: object, value: float, message: str) -> None:
    """`ctl clock --scale 10000.0001` and `--step 3600.0001` (and the control channel's `clock` and
    `step`) said "got 10000" and "got 3600"."""
    with pytest.raises(ValueError) as refused:
        check(value)  # type: ignore[operator]
    assert str(refused.value) == message


def test_a_refused_scale_leaves_the_clock_as_it_was() -> None:
    clock = ScaledClock(1.0)
    with pytest.raises(ValueError, match=r"got 10000\.0001$"):
        clock.set_scale(10000.0001)
    assert clock.scale == 1.0 and MIN_SCALE <= clock.scale <= MAX_SCALE


def test_a_fault_count_just_off_a_whole_number_is_shown_as_given() -> None:
    with pytest.raises(ValueError, match=r"^count must be a whole number, got 1\.0000001$"):
        fault_params("drop", {"count": 1.0000001})


def test_a_profile_bound_is_shown_exactly() -> None:
    """A bound with more digits than `:g` keeps (INT32_MAX, the MP-285's longest count) read as
    `<= 2.14748e+09`, below the value it refused."""
    with pytest.raises(SchemaError) as refused:
        Int(1, INT32_MAX).check(INT32_MAX + 1, ("limits",))
    assert refused.value.message == "2147483648 is out of range (>= 1, <= 2147483647)"
    assert Int(1, INT32_MAX).describe() == "int >= 1, <= 2147483647"


@pytest.mark.parametrize("check", [check_scale, check_step])
def test_an_integer_past_the_float_range_is_refused_not_raised(check: object) -> None:
    """JSON integers have no size limit: `{"op": "clock", "scale": 1000...0}` with 400 digits made
    `math.isfinite` raise OverflowError, a traceback from the control channel."""
    with pytest.raises(ValueError, match="must be a finite number"):
        check(10**400)  # type: ignore[operator]
    with pytest.raises(ValueError, match=r"^ms must be a number >= 0 and <= 60000"):
        fault_params("latency", {"ms": 10**400})
